// Keypoints and descriptors of one image, with the 3D point of each keypoint where the frame has
// depth: what registration, place recognition and photo matching consume.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/features.h"

namespace sightmap::slam {

struct FeatureOptions {
  // kSift is refused by Check(): everything downstream takes binary ORB descriptors.
  enum class Type { kOrb, kSift };
  Type type = Type::kOrb;
  // Keypoints kept per image, spread over a grid so one textured poster cannot take them all.
  int max_features = 1000;
  int grid_cols = 8;  // cells across the image
  int grid_rows = 6;  // cells down the image
  // ORB scale pyramid.
  int orb_levels = 8;
  double orb_scale_factor = 1.2;
  // ORB's FAST threshold; lowered per cell when a low-texture cell finds too few corners.
  int orb_fast_threshold = 20;
  // Depth outside [min_depth_m, max_depth_m] is not trusted for a 3D point (Kinect-class sensors
  // measure 0.5-8 m; noise grows with the square of depth, and registration weighs each point by
  // that noise) [m].
  double min_depth_m = 0.4;
  double max_depth_m = 8.0;
  // Corners often sit on depth edges, where the depth under a keypoint may belong to the
  // foreground or the background: a keypoint gets no 3D point when the depth within
  // depth_window_radius_px varies by more than depth_edge_ratio x its depth (holes ignored).
  int depth_window_radius_px = 1;
  double depth_edge_ratio = 0.05;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const FeatureOptions& options);
void from_json(const nlohmann::json& json, FeatureOptions& options);

// Detects and describes features in a BGR or grey image; with a depth image (16-bit mm, same size,
// registered), each keypoint whose depth is valid gets its 3D point through `camera`. Pass an
// empty depth for a photo without depth.
Features ExtractFeatures(const cv::Mat& image, const cv::Mat& depth_mm, const Intrinsics& camera,
                         const FeatureOptions& options = FeatureOptions());

}  // namespace sightmap::slam
