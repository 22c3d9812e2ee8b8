// The features of one image, as every layer sees them: the mapper extracts and registers them
// (slam/features.h), the model stores them (store/), the locator matches photos against them
// (identify/).
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace sightmap {

// points_cam[i] is the camera-frame point [m] of keypoints[i], valid when has_point[i];
// descriptors has one row per keypoint (CV_8U for ORB, CV_32F for SIFT). A photo without depth
// has no points (points_cam and has_point empty).
struct Features {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  std::vector<Eigen::Vector3d> points_cam;
  std::vector<bool> has_point;

  size_t size() const { return keypoints.size(); }
  size_t NumPoints() const;
  // A point slot (points_cam and has_point) per keypoint, or none at all.
  bool PointsMatchKeypoints() const;
  // One descriptor row per keypoint, and PointsMatchKeypoints().
  bool IsConsistent() const;
};

}  // namespace sightmap
