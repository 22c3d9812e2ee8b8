// Re-projects a depth image into the colour camera, so that depth pixel (u, v) measures the surface
// seen by colour pixel (u, v). Needed when the sensor did not register in hardware: the depth and
// colour cameras of a Kinect/Xtion sit 2.3-2.6 cm apart, which shifts a 2 m point by ~7 px.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"

namespace sightmap::capture {

struct DepthToColorModel {
  Intrinsics depth;  // the depth camera, at the depth image's size
  Intrinsics color;  // the colour camera, at the size the output should have
  Eigen::Isometry3d color_from_depth = Eigen::Isometry3d::Identity();  // [m]
};

// Returns a CV_16UC1 image of color.width x color.height in millimetres, 0 where nothing projects.
// Where several depth pixels land on one colour pixel the nearest surface wins (occlusion); where
// the colour image is finer than the depth image, each depth pixel covers its footprint so the
// result has no sampling holes.
cv::Mat RegisterDepthToColor(const cv::Mat& depth_mm, const DepthToColorModel& model);

// The family default for PrimeSense-based sensors (Kinect v1, Xtion, Carmine): same orientation,
// the colour camera `baseline_m` to the depth camera's +x (the device's right as seen from behind,
// images not mirrored). The PS1080 driver records the baseline as DCMOS_RCMOS_DISTANCE.
Eigen::Isometry3d PrimeSenseColorFromDepth(double baseline_m);

}  // namespace sightmap::capture
