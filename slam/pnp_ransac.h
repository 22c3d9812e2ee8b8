// A camera's pose from 2D-3D correspondences with outliers: RANSAC over minimal P3P samples.
//
// The sampling, scoring and stopping are OpenCV's solvePnPRansac with SOLVEPNP_AP3P (the same
// random draws from the same seed, the same inlier test in single precision, the same adaptive
// iteration count, EPnP on the best sample's inliers), so a caller moved from OpenCV keeps its
// answers. What differs is the cost of a sample: OpenCV's solves each one through solvePnP's
// generic path (matrix wrapping, undistortion, four projectPoints calls) at ~45 us, and scores it
// with projectPoints; here a sample is Kneip's P3P (OpenGV) on precomputed bearing vectors and a
// plain projection loop, a few microseconds (slam/pnp_ransac_benchmark).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace sightmap::slam {

struct PnpRansacOptions {
  // Samples drawn at most; fewer once the best sample's inlier share makes `confidence` certain.
  int max_iterations = 500;
  // A correspondence is an inlier when it reprojects within this distance [px].
  double reprojection_px = 4.0;
  // Probability that at least one sample drawn was all inliers, for the adaptive count (0, 1).
  double confidence = 0.999;

  bool Check(std::string* error) const;
};

struct PnpRansacResult {
  bool found = false;
  // cam_from_world in OpenCV's convention (x_cam = R(rvec) * x_world + tvec): EPnP on the
  // inliers of the best sample.
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  std::vector<int> inliers;  // indices into the correspondences, ascending (of the best sample)
  int samples = 0;           // drawn, for the caller's statistics
};

// `object` world points [m] and `image` pixels correspond by index; `camera` is a pinhole
// (fx, fy, cx, cy; no skew, no distortion). Fewer than 4 correspondences: not found. Exactly 4:
// their P3P pose, all inliers (as OpenCV). Throws Error on mismatched sizes or bad options.
PnpRansacResult SolvePnpRansac(const std::vector<cv::Point3f>& object,
                               const std::vector<cv::Point2f>& image, const cv::Matx33d& camera,
                               const PnpRansacOptions& options);

// RANSAC's adaptive count: the samples needed to draw one without outliers with probability
// `confidence` when `outlier_share` of the correspondences are outliers, at most `max_iterations`
// (OpenCV's RANSACUpdateNumIters, rounding included).
int RansacIterations(double confidence, double outlier_share, int sample_size, int max_iterations);

}  // namespace sightmap::slam
