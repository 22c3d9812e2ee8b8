#include "slam/trajectory_plot.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/check.h"

namespace sightmap::slam {
namespace {

bool HasColor(const cv::Mat& image, const cv::Scalar& color) {
  const cv::Vec3b wanted(static_cast<uchar>(color[0]), static_cast<uchar>(color[1]),
                         static_cast<uchar>(color[2]));
  for (int row = 0; row < image.rows; ++row) {
    for (int column = 0; column < image.cols; ++column) {
      if (image.at<cv::Vec3b>(row, column) == wanted) return true;
    }
  }
  return false;
}

cv::Vec3b ToVec(const cv::Scalar& color) {
  return cv::Vec3b(static_cast<uchar>(color[0]), static_cast<uchar>(color[1]),
                   static_cast<uchar>(color[2]));
}

// The ground truth walks the rectangle (0,0)-(4,0)-(4,2)-(0,2) at z = 1.5 m; the aligned estimate
// is the same rectangle shrunk by 10% about its centre, so it lies inside the ground truth's box.
TrajectoryError RectangleError() {
  TrajectoryError error;
  const Eigen::Vector3d corners[] = {{0, 0, 1.5}, {4, 0, 1.5}, {4, 2, 1.5}, {0, 2, 1.5}};
  const Eigen::Vector3d centre(2, 1, 1.5);
  for (int side = 0; side < 4; ++side) {
    for (int step = 0; step < 10; ++step) {
      const Eigen::Vector3d p =
          corners[side] + (corners[(side + 1) % 4] - corners[side]) * (step / 10.0);
      error.gt_positions.push_back(p);
      error.aligned_positions.push_back(centre + 0.9 * (p - centre));
    }
  }
  error.matched_poses = static_cast<int>(error.gt_positions.size());
  error.ate_rmse_m = 0.123;
  error.ate_max_m = 0.2;
  return error;
}

TrajectoryPlotOptions SmallPlot() {
  TrajectoryPlotOptions options;
  options.width_px = 640;
  options.height_px = 480;
  options.margin_px = 40;
  options.header_px = 60;
  return options;
}

TEST(TrajectoryPlot, HasTheRequestedSizeAndBothTrajectoryColours) {
  const cv::Mat image = DrawTrajectoryPlot(RectangleError(), SmallPlot());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
  EXPECT_EQ(image.type(), CV_8UC3);
  // Not blank: far from every pixel being the white background.
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(gray < 250), 2000);
  EXPECT_TRUE(HasColor(image, kPlotGroundTruthColor));
  EXPECT_TRUE(HasColor(image, kPlotEstimateColor));
  EXPECT_TRUE(HasColor(image, kPlotErrorColor));

  TrajectoryPlotOptions no_segments = SmallPlot();
  no_segments.draw_error_segments = false;
  EXPECT_FALSE(HasColor(DrawTrajectoryPlot(RectangleError(), no_segments), kPlotErrorColor));
}

TEST(TrajectoryPlot, KnownPointLandsAtTheExpectedPixel) {
  // Plot area: columns 40..600 (560 px), rows 100..440 (340 px), centre (320, 270). The box is
  // 4 m x 2 m: min(560 / 4, 340 / 2) = 140 px/m, so x spans columns 40..600 and y (up) rows
  // 410..130. The ground truth's start (0, 0) is at (40, 410); z (up) is dropped.
  const TrajectoryError error = RectangleError();
  const TrajectoryPlotLayout layout(error.gt_positions, SmallPlot());
  EXPECT_DOUBLE_EQ(layout.pixels_per_m(), 140.0);
  const cv::Point2d start = layout.ToPixel(Eigen::Vector3d(0, 0, 1.5));
  EXPECT_NEAR(start.x, 40.0, 1e-9);
  EXPECT_NEAR(start.y, 410.0, 1e-9);
  const cv::Point2d far_corner = layout.ToPixel(Eigen::Vector3d(4, 2, -7.0));
  EXPECT_NEAR(far_corner.x, 600.0, 1e-9);
  EXPECT_NEAR(far_corner.y, 130.0, 1e-9);
  EXPECT_EQ(layout.horizontal_name(), "x");
  EXPECT_EQ(layout.upward_name(), "y");

  const cv::Mat image = DrawTrajectoryPlot(error, SmallPlot());
  EXPECT_EQ(image.at<cv::Vec3b>(410, 40), ToVec(kPlotGroundTruthColor));
  EXPECT_EQ(image.at<cv::Vec3b>(130, 600), ToVec(kPlotGroundTruthColor));
  // The estimate's start, (0.2, 0.1): 28 px right of and 14 px above the ground truth's.
  EXPECT_EQ(image.at<cv::Vec3b>(396, 68), ToVec(kPlotEstimateColor));
  // The middle of the rectangle is empty floor.
  EXPECT_NE(image.at<cv::Vec3b>(270, 320), ToVec(kPlotGroundTruthColor));
  EXPECT_NE(image.at<cv::Vec3b>(270, 320), ToVec(kPlotEstimateColor));
}

TEST(TrajectoryPlot, CameraFrameWorldIsSeenFromAbove) {
  // A world anchored at a camera frame has y down: up = -y, and the plot shows x right, z up.
  TrajectoryPlotOptions options = SmallPlot();
  options.up_axis = 1;
  options.up_sign = -1;
  const TrajectoryPlotLayout layout({{0, 5, 0}, {4, -3, 2}}, options);
  EXPECT_EQ(layout.horizontal_name(), "x");
  EXPECT_EQ(layout.upward_name(), "z");
  const cv::Point2d origin = layout.ToPixel(Eigen::Vector3d(0, 0, 0));
  EXPECT_NEAR(origin.x, 40.0, 1e-9);
  EXPECT_NEAR(origin.y, 410.0, 1e-9);
}

TEST(TrajectoryPlot, RefusesBadOptions) {
  TrajectoryPlotOptions options = SmallPlot();
  options.up_axis = 3;
  EXPECT_THROW(DrawTrajectoryPlot(RectangleError(), options), InvalidArgument);
  options = SmallPlot();
  options.width_px = 10;
  EXPECT_THROW(DrawTrajectoryPlot(RectangleError(), options), InvalidArgument);
}

}  // namespace
}  // namespace sightmap::slam
