#include "identify/view_agreement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/statistics.h"

namespace sightmap::identify {

bool ViewAgreementOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (thumbnail_width_px < 16 || photo_side_px < 16)
    why << "thumbnail_width_px and photo_side_px must be at least 16";
  else if (!(min_depth_m > 0.0) || !(max_depth_m > min_depth_m))
    why << "min_depth_m must be positive and below max_depth_m";
  else if (zbuffer_cell_px < 1 || !(occlusion_margin_ratio >= 0.0))
    why << "zbuffer_cell_px must be positive, occlusion_margin_ratio not negative";
  else if (min_cell_samples < 2 || !(min_cell_std >= 0.0))
    why << "min_cell_samples must be at least 2, min_cell_std not negative";
  else if (min_samples < 2 || min_cells < 1 || min_cells > 64)
    why << "min_samples must be at least 2, min_cells in [1, 64]";
  if (why.tellp() == 0) return true;
  if (error != nullptr) *error = "ViewAgreementOptions: " + why.str();
  return false;
}

size_t KeyframeThumbnail::Bytes() const {
  return grey.total() * grey.elemSize() + depth_mm.total() * depth_mm.elemSize();
}

KeyframeThumbnail MakeThumbnail(const cv::Mat& color_or_grey, const cv::Mat& depth_mm,
                                const Intrinsics& intrinsics, const ViewAgreementOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  if (color_or_grey.empty() || depth_mm.type() != CV_16UC1 || depth_mm.cols != intrinsics.width ||
      depth_mm.rows != intrinsics.height) {
    SIGHTMAP_THROW(InvalidArgument,
                   "MakeThumbnail needs a colour image and a 16-bit depth image "
                   "of the intrinsics' size");
  }
  const int width = std::min(options.thumbnail_width_px, depth_mm.cols);
  const int height = std::max(
      1, static_cast<int>(std::lround(static_cast<double>(depth_mm.rows) * width / depth_mm.cols)));
  KeyframeThumbnail thumbnail;
  cv::Mat grey = color_or_grey;
  if (grey.channels() == 3) cv::cvtColor(color_or_grey, grey, cv::COLOR_BGR2GRAY);
  SIGHTMAP_CHECK(grey.type() == CV_8UC1, "MakeThumbnail: an 8-bit image is needed");
  cv::resize(grey, thumbnail.grey, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  // Depth at the thumbnail pixels' centres, not averaged: a mean across a depth edge places a
  // pixel in the air between two surfaces.
  thumbnail.depth_mm.create(height, width, CV_16UC1);
  for (int v = 0; v < height; ++v) {
    const int row =
        std::min(depth_mm.rows - 1, static_cast<int>((v + 0.5) * depth_mm.rows / height));
    for (int u = 0; u < width; ++u) {
      const int col =
          std::min(depth_mm.cols - 1, static_cast<int>((u + 0.5) * depth_mm.cols / width));
      thumbnail.depth_mm.at<uint16_t>(v, u) = depth_mm.at<uint16_t>(row, col);
    }
  }
  thumbnail.intrinsics = intrinsics.Scaled(width, height);
  return thumbnail;
}

cv::Mat AgreementImage(const cv::Mat& photo, const ViewAgreementOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!photo.empty(), "AgreementImage: the photo is empty");
  cv::Mat grey = photo;
  if (photo.channels() == 3) cv::cvtColor(photo, grey, cv::COLOR_BGR2GRAY);
  if (photo.channels() == 4) cv::cvtColor(photo, grey, cv::COLOR_BGRA2GRAY);
  const double scale =
      std::min(1.0, static_cast<double>(options.photo_side_px) / std::max(grey.cols, grey.rows));
  cv::Mat small;
  cv::resize(grey, small, cv::Size(), scale, scale, cv::INTER_AREA);
  cv::Mat blurred;
  small.convertTo(blurred, CV_32F);
  cv::GaussianBlur(blurred, blurred, cv::Size(3, 3), 0.0);
  return blurred;
}

double ViewAgreement::Score() const { return std::min(global_ncc, cell_median_ncc); }

namespace {

constexpr int kGrid = 8;  // cells per side of the photo for the local correlations

// A keyframe pixel's grey level and where it lands in the photo image.
struct Sample {
  float u = 0.0f;
  float v = 0.0f;
  float depth = 0.0f;  // in the photo's camera [m]
  float grey = 0.0f;   // the keyframe's
};

std::vector<Sample> ProjectKeyframe(const cv::Mat& image, const Intrinsics& photo_camera,
                                    const Eigen::Isometry3d& photo_from_keyframe,
                                    const KeyframeThumbnail& keyframe,
                                    const ViewAgreementOptions& options) {
  std::vector<Sample> samples;
  const cv::Mat& depth = keyframe.depth_mm;
  samples.reserve(depth.total());
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const double z = 1e-3 * depth.at<uint16_t>(v, u);
      if (z < options.min_depth_m || z > options.max_depth_m) continue;
      const Eigen::Vector3d in_photo = photo_from_keyframe * keyframe.intrinsics.Unproject(u, v, z);
      if (in_photo.z() < options.min_depth_m) continue;
      const Eigen::Vector2d p = photo_camera.Project(in_photo);
      // Bilinear sampling needs the pixel's right and lower neighbours.
      if (!(p.x() >= 0.0 && p.y() >= 0.0 && p.x() < image.cols - 1 && p.y() < image.rows - 1))
        continue;
      samples.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(in_photo.z()),
                         static_cast<float>(keyframe.grey.at<uint8_t>(v, u))});
    }
  }
  return samples;
}

// Drops samples hidden behind a nearer one in the same z-buffer cell: the photo sees the nearer
// surface there.
std::vector<Sample> KeepVisible(std::vector<Sample> samples, const cv::Size& image_size,
                                const ViewAgreementOptions& options) {
  const int cell = options.zbuffer_cell_px;
  const int cols = (image_size.width + cell - 1) / cell;
  const int rows = (image_size.height + cell - 1) / cell;
  std::vector<float> nearest(static_cast<size_t>(cols * rows), std::numeric_limits<float>::max());
  auto index = [&](const Sample& s) {
    return static_cast<size_t>(static_cast<int>(s.v) / cell * cols + static_cast<int>(s.u) / cell);
  };
  for (const Sample& s : samples) nearest[index(s)] = std::min(nearest[index(s)], s.depth);
  const float ratio = static_cast<float>(1.0 + options.occlusion_margin_ratio);
  samples.erase(
      std::remove_if(samples.begin(), samples.end(),
                     [&](const Sample& s) { return s.depth > nearest[index(s)] * ratio; }),
      samples.end());
  return samples;
}

float Bilinear(const cv::Mat& image, float u, float v) {
  const int x = static_cast<int>(u);
  const int y = static_cast<int>(v);
  const float a = u - static_cast<float>(x);
  const float b = v - static_cast<float>(y);
  const float* row0 = image.ptr<float>(y);
  const float* row1 = image.ptr<float>(y + 1);
  return (1 - b) * ((1 - a) * row0[x] + a * row0[x + 1]) +
         b * ((1 - a) * row1[x] + a * row1[x + 1]);
}

// Sums for a zero-mean normalised cross-correlation.
struct Correlation {
  double n = 0.0, sa = 0.0, sb = 0.0, saa = 0.0, sbb = 0.0, sab = 0.0;
  void Add(double a, double b) {
    n += 1.0;
    sa += a;
    sb += b;
    saa += a * a;
    sbb += b * b;
    sab += a * b;
  }
  double VarA() const { return n > 0 ? std::max(0.0, saa / n - (sa / n) * (sa / n)) : 0.0; }
  double VarB() const { return n > 0 ? std::max(0.0, sbb / n - (sb / n) * (sb / n)) : 0.0; }
  double Ncc() const {
    const double denominator = std::sqrt(VarA() * VarB());
    if (!(denominator > 0.0)) return 0.0;
    return (sab / n - (sa / n) * (sb / n)) / denominator;
  }
};

}  // namespace

ViewAgreement MeasureViewAgreement(const cv::Mat& image, const Intrinsics& intrinsics,
                                   const Eigen::Isometry3d& world_from_photo,
                                   const KeyframeThumbnail& keyframe,
                                   const Eigen::Isometry3d& world_from_keyframe,
                                   const ViewAgreementOptions& options) {
  return MeasureViewAgreement(image, intrinsics, world_from_photo,
                              {PlacedThumbnail{&keyframe, world_from_keyframe}}, options);
}

ViewAgreement MeasureViewAgreement(const cv::Mat& image, const Intrinsics& intrinsics,
                                   const Eigen::Isometry3d& world_from_photo,
                                   const std::vector<PlacedThumbnail>& keyframes,
                                   const ViewAgreementOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(image.type() == CV_32FC1, "MeasureViewAgreement: use AgreementImage's image");
  const Intrinsics photo_camera = intrinsics.Scaled(image.cols, image.rows);
  const Eigen::Isometry3d photo_from_world = world_from_photo.inverse();
  std::vector<Sample> projected;
  for (const PlacedThumbnail& keyframe : keyframes) {
    SIGHTMAP_CHECK(keyframe.thumbnail != nullptr, "MeasureViewAgreement: a keyframe is null");
    std::vector<Sample> samples =
        ProjectKeyframe(image, photo_camera, photo_from_world * keyframe.world_from_keyframe,
                        *keyframe.thumbnail, options);
    if (projected.empty()) {
      projected = std::move(samples);  // the one keyframe of most checks: no copy
    } else {
      projected.insert(projected.end(), samples.begin(), samples.end());
    }
  }
  const std::vector<Sample> samples = KeepVisible(std::move(projected), image.size(), options);

  Correlation global;
  std::array<Correlation, kGrid * kGrid> cells;
  for (const Sample& s : samples) {
    const double photo_grey = Bilinear(image, s.u, s.v);
    global.Add(s.grey, photo_grey);
    const int cx = std::min(kGrid - 1, static_cast<int>(s.u * kGrid / image.cols));
    const int cy = std::min(kGrid - 1, static_cast<int>(s.v * kGrid / image.rows));
    cells[static_cast<size_t>(cy * kGrid + cx)].Add(s.grey, photo_grey);
  }
  std::vector<double> cell_nccs;
  const double min_var = options.min_cell_std * options.min_cell_std;
  for (const Correlation& c : cells) {
    if (c.n < options.min_cell_samples || c.VarA() < min_var || c.VarB() < min_var) continue;
    cell_nccs.push_back(c.Ncc());
  }
  ViewAgreement agreement;
  agreement.samples = static_cast<int>(samples.size());
  agreement.cells = static_cast<int>(cell_nccs.size());
  if (agreement.samples < options.min_samples || agreement.cells < options.min_cells) {
    return agreement;
  }
  agreement.judged = true;
  agreement.global_ncc = global.Ncc();
  agreement.cell_median_ncc = Percentile(cell_nccs, 0.5);
  return agreement;
}

SIGHTMAP_OPTIONS_JSON(ViewAgreementOptions, thumbnail_width_px, photo_side_px, min_depth_m,
                      max_depth_m, zbuffer_cell_px, occlusion_margin_ratio, min_cell_samples,
                      min_cell_std, min_samples, min_cells)

}  // namespace sightmap::identify
