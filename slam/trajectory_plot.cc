#include "slam/trajectory_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "core/check.h"

namespace sightmap::slam {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kBackground(255, 255, 255);
const cv::Scalar kGridColor(228, 228, 228);
const cv::Scalar kFrameColor(190, 190, 190);
const cv::Scalar kTextColor(40, 40, 40);

std::string AxisName(const Eigen::Vector3d& axis) {
  for (int i = 0; i < 3; ++i) {
    if (std::abs(axis(i)) > 0.5) return std::string(axis(i) < 0 ? "-" : "") + "xyz"[i];
  }
  return "?";
}

// The smallest 1, 2 or 5 x 10^k metres that is at least `min_m` long.
double NiceSpacing(double min_m) {
  double spacing = std::pow(10.0, std::floor(std::log10(min_m)));
  for (const double factor : {1.0, 2.0, 5.0, 10.0}) {
    if (spacing * factor >= min_m) return spacing * factor;
  }
  return spacing * 10.0;
}

std::string FormatMetres(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", std::abs(value) < 1e-9 ? 0.0 : value);
  return text;
}

cv::Point Round(const cv::Point2d& p) { return cv::Point(cvRound(p.x), cvRound(p.y)); }

void DrawText(cv::Mat* image, const std::string& text, cv::Point origin, double scale,
              bool right_aligned = false) {
  if (right_aligned) {
    int baseline = 0;
    origin.x -= cv::getTextSize(text, kFont, scale, 1, &baseline).width;
  }
  cv::putText(*image, text, origin, kFont, scale, kTextColor, 1, cv::LINE_AA);
}

void DrawPath(cv::Mat* image, const TrajectoryPlotLayout& layout,
              const std::vector<Eigen::Vector3d>& positions, const cv::Scalar& color, int thickness,
              int start_radius) {
  if (positions.empty()) return;
  std::vector<cv::Point> pixels;
  for (const Eigen::Vector3d& position : positions) {
    pixels.push_back(Round(layout.ToPixel(position)));
  }
  cv::polylines(*image, pixels, false, color, thickness, cv::LINE_8);
  cv::circle(*image, pixels.front(), start_radius, color, cv::FILLED, cv::LINE_8);
}

}  // namespace

bool TrajectoryPlotOptions::Check(std::string* error) const {
  std::string problem;
  if (width_px < 64 || height_px < 64 || width_px > 16384 || height_px > 16384) {
    problem = "the plot must be 64..16384 pixels wide and high";
  } else if (margin_px < 0 || header_px < 0 || 2 * margin_px + 16 > width_px ||
             2 * margin_px + header_px + 16 > height_px) {
    problem = "margin and header leave no room for the plot";
  } else if (up_axis < 0 || up_axis > 2 || (up_sign != 1 && up_sign != -1)) {
    problem = "up_axis must be 0, 1 or 2 and up_sign +1 or -1";
  }
  if (problem.empty()) return true;
  if (error) *error = problem;
  return false;
}

TrajectoryPlotLayout::TrajectoryPlotLayout(const std::vector<Eigen::Vector3d>& points,
                                           const TrajectoryPlotOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const Eigen::Vector3d up = options.up_sign * Eigen::Vector3d::Unit(options.up_axis);
  horizontal_ = Eigen::Vector3d::Unit(options.up_axis == 0 ? 1 : 0);
  upward_ = up.cross(horizontal_);
  horizontal_name_ = AxisName(horizontal_);
  upward_name_ = AxisName(upward_);

  Eigen::Vector2d low(-1.0, -1.0);
  Eigen::Vector2d high(1.0, 1.0);
  if (!points.empty()) {
    low = high = ToPlane(points.front());
    for (const Eigen::Vector3d& point : points) {
      low = low.cwiseMin(ToPlane(point));
      high = high.cwiseMax(ToPlane(point));
    }
  }
  const double area_width = options.width_px - 2.0 * options.margin_px;
  const double area_height = options.height_px - 2.0 * options.margin_px - options.header_px;
  const Eigen::Vector2d range = (high - low).cwiseMax(1e-9);
  pixels_per_m_ = std::min(area_width / range.x(), area_height / range.y());
  // A (nearly) stationary trajectory still shows at least 10 cm around it.
  pixels_per_m_ = std::min(pixels_per_m_, std::min(area_width, area_height) / 0.1);
  plane_centre_ = 0.5 * (low + high);
  pixel_centre_ = cv::Point2d(options.margin_px + 0.5 * area_width,
                              options.header_px + options.margin_px + 0.5 * area_height);
}

Eigen::Vector2d TrajectoryPlotLayout::ToPlane(const Eigen::Vector3d& world) const {
  return Eigen::Vector2d(horizontal_.dot(world), upward_.dot(world));
}

cv::Point2d TrajectoryPlotLayout::ToPixel(const Eigen::Vector3d& world) const {
  const Eigen::Vector2d offset = (ToPlane(world) - plane_centre_) * pixels_per_m_;
  return cv::Point2d(pixel_centre_.x + offset.x(), pixel_centre_.y - offset.y());
}

cv::Mat DrawTrajectoryPlot(const TrajectoryError& error, const TrajectoryPlotOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(error.gt_positions.size() == error.aligned_positions.size(),
                 "DrawTrajectoryPlot: " << error.gt_positions.size() << " ground-truth but "
                                        << error.aligned_positions.size()
                                        << " estimated positions");
  std::vector<Eigen::Vector3d> all = error.gt_positions;
  all.insert(all.end(), error.aligned_positions.begin(), error.aligned_positions.end());
  const TrajectoryPlotLayout layout(all, options);
  cv::Mat image(options.height_px, options.width_px, CV_8UC3, kBackground);

  // Plot area, grid lines every `spacing` metres (at least 50 px apart), labelled in metres.
  const int left = options.margin_px;
  const int right = options.width_px - options.margin_px;
  const int top = options.header_px + options.margin_px;
  const int bottom = options.height_px - options.margin_px;
  const double ppm = layout.pixels_per_m();
  const double spacing = NiceSpacing(50.0 / ppm);
  // Plane coordinates of the area's edges: invert ToPixel on the area corners.
  const Eigen::Vector2d centre_plane =
      layout.ToPlane(all.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(all.front()));
  const cv::Point2d centre_pixel =
      layout.ToPixel(all.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(all.front()));
  const auto plane_x = [&](double column) {
    return centre_plane.x() + (column - centre_pixel.x) / ppm;
  };
  const auto plane_y = [&](double row) { return centre_plane.y() - (row - centre_pixel.y) / ppm; };
  const auto column_of = [&](double x) { return centre_pixel.x + (x - centre_plane.x()) * ppm; };
  const auto row_of = [&](double y) { return centre_pixel.y - (y - centre_plane.y()) * ppm; };
  for (double x = std::ceil(plane_x(left) / spacing) * spacing; x <= plane_x(right); x += spacing) {
    const int column = cvRound(column_of(x));
    cv::line(image, {column, top}, {column, bottom}, kGridColor, 1, cv::LINE_8);
    DrawText(&image, FormatMetres(x), {column - 8, bottom + 14}, 0.35);
  }
  for (double y = std::ceil(plane_y(bottom) / spacing) * spacing; y <= plane_y(top); y += spacing) {
    const int row = cvRound(row_of(y));
    cv::line(image, {left, row}, {right, row}, kGridColor, 1, cv::LINE_8);
    DrawText(&image, FormatMetres(y), {left - 4, row + 4}, 0.35, true);
  }
  cv::rectangle(image, {left, top}, {right, bottom}, kFrameColor, 1, cv::LINE_8);

  // Scale bar in the bottom margin, right-aligned with the plot area.
  const int bar_row = options.height_px - std::max(4, options.margin_px / 4);
  const int bar_length = cvRound(spacing * ppm);
  cv::line(image, {right - bar_length, bar_row}, {right, bar_row}, kTextColor, 2, cv::LINE_8);
  cv::line(image, {right - bar_length, bar_row - 4}, {right - bar_length, bar_row + 4}, kTextColor,
           1, cv::LINE_8);
  cv::line(image, {right, bar_row - 4}, {right, bar_row + 4}, kTextColor, 1, cv::LINE_8);
  DrawText(&image, FormatMetres(spacing) + " m", {right - bar_length - 8, bar_row + 4}, 0.45, true);

  // Error segments under the paths, the ground truth (thick) under the estimate (thin) so both
  // stay visible where they coincide; a dot marks each start.
  if (options.draw_error_segments) {
    for (size_t i = 0; i < error.gt_positions.size(); ++i) {
      cv::line(image, Round(layout.ToPixel(error.gt_positions[i])),
               Round(layout.ToPixel(error.aligned_positions[i])), kPlotErrorColor, 1, cv::LINE_8);
    }
  }
  DrawPath(&image, layout, error.gt_positions, kPlotGroundTruthColor, 4, 6);
  DrawPath(&image, layout, error.aligned_positions, kPlotEstimateColor, 2, 3);

  // Legend, view and ATE in the header band.
  const int legend_row = std::max(14, options.header_px / 2 - 8);
  int x = left;
  const auto legend_entry = [&](const cv::Scalar& color, int thickness, const std::string& label) {
    cv::line(image, {x, legend_row - 4}, {x + 28, legend_row - 4}, color, thickness, cv::LINE_8);
    DrawText(&image, label, {x + 34, legend_row}, 0.45);
    int baseline = 0;
    x += 34 + cv::getTextSize(label, kFont, 0.45, 1, &baseline).width + 20;
  };
  legend_entry(kPlotGroundTruthColor, 4, "ground truth");
  legend_entry(kPlotEstimateColor, 2, "estimate (aligned)");
  if (options.draw_error_segments) legend_entry(kPlotErrorColor, 1, "error");
  DrawText(&image,
           "top view: " + layout.horizontal_name() + " right, " + layout.upward_name() + " up",
           {right, legend_row}, 0.45, true);
  char ate[128];
  std::snprintf(ate, sizeof(ate), "ATE RMSE %.4g m  (max %.4g m, %d matched poses)",
                error.ate_rmse_m, error.ate_max_m, error.matched_poses);
  DrawText(&image, ate, {left, legend_row + 24}, 0.55);
  return image;
}

}  // namespace sightmap::slam
