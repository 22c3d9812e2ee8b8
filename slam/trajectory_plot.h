// A top-down plot of a trajectory evaluation (slam/trajectory_eval.h): the ground truth and the
// aligned estimate drawn on the floor plan, with a metric grid and scale bar, a legend, optional
// error segments between matched pairs, and the ATE RMSE.
//
// World frame: ARCHITECTURE.md fixes the camera frame (x right, y down, z forward) and names poses
// world_from_cam, but the world's up direction is the ground truth's own. The simulator's world
// (sim/scene.h) and motion-capture ground truth have z up, so by default the plot drops z and shows
// x to the right and y up, seen from above. A ground truth anchored at a camera frame (y down) is
// drawn from above with up_axis = 1, up_sign = -1: x to the right, z up the image.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slam/trajectory_eval.h"

namespace sightmap::slam {

struct TrajectoryPlotOptions {
  // Image size [px].
  int width_px = 1000;
  int height_px = 800;
  // Blank border on every side [px], and the band at the top for the legend and the ATE [px].
  int margin_px = 40;
  int header_px = 60;
  // The world axis pointing up (0 = x, 1 = y, 2 = z) and its sign (+1 or -1): the plot drops it
  // and looks down along -up. The image's horizontal axis is the first other world axis (x, or y
  // when x is up); the image's upward axis is up x horizontal, so the view is never mirrored.
  int up_axis = 2;
  int up_sign = 1;
  // Draw a thin segment from each ground-truth position to its matched aligned estimate.
  bool draw_error_segments = true;

  bool Check(std::string* error) const;
};

// Where world points land in a plot: the trajectories' bounding box on the floor plane, scaled
// uniformly to fill the plot area (the image less margin_px on every side and header_px at the
// top) and centred in it.
class TrajectoryPlotLayout {
 public:
  TrajectoryPlotLayout(const std::vector<Eigen::Vector3d>& points,
                       const TrajectoryPlotOptions& options);

  // The floor-plane coordinates of a world point [m]: (horizontal, upward in the image).
  Eigen::Vector2d ToPlane(const Eigen::Vector3d& world) const;
  // The pixel (column, row) of a world point, sub-pixel.
  cv::Point2d ToPixel(const Eigen::Vector3d& world) const;
  double pixels_per_m() const { return pixels_per_m_; }
  // Names of the plotted axes, e.g. "x" and "y", or "-z" when the image shows the negative axis.
  const std::string& horizontal_name() const { return horizontal_name_; }
  const std::string& upward_name() const { return upward_name_; }

 private:
  Eigen::Vector3d horizontal_;
  Eigen::Vector3d upward_;
  std::string horizontal_name_;
  std::string upward_name_;
  double pixels_per_m_ = 1.0;
  Eigen::Vector2d plane_centre_ = Eigen::Vector2d::Zero();
  cv::Point2d pixel_centre_;
};

// Colours (BGR) of the plot's elements, so tests and documentation can name them.
inline const cv::Scalar kPlotGroundTruthColor(0, 150, 0);  // green
inline const cv::Scalar kPlotEstimateColor(0, 0, 220);     // red
inline const cv::Scalar kPlotErrorColor(235, 170, 120);    // light blue

// Draws `error.gt_positions` and `error.aligned_positions` (matched pairs) as a BGR image of
// options.width_px x options.height_px. Throws InvalidArgument on bad options.
cv::Mat DrawTrajectoryPlot(const TrajectoryError& error,
                           const TrajectoryPlotOptions& options = TrajectoryPlotOptions());

}  // namespace sightmap::slam
