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
  // kOrb: binary 32-byte descriptors, what tracking, the vocabulary and the place index take.
  // kSift: RootSIFT (Arandjelovic & Zisserman 2012: SIFT L1-normalised, square-rooted, so that
  // Euclidean distance compares as the Hellinger kernel), stored as 128 bytes per row
  // (kRootSiftScale per unit), for matching phone photos, whose viewpoint and scale differ more
  // from the keyframes' than one keyframe's from the next.
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
  // SIFT's contrast threshold (OpenCV's, per octave layer): lower finds more keypoints on the
  // low-contrast walls and ceilings of an office.
  double sift_contrast_threshold = 0.04;
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

// A RootSIFT descriptor's components lie in [0, 1] (its L2 norm is 1); stored as bytes, one unit is
// this many steps, so a byte row's L2 distance / kRootSiftScale is the descriptors' distance.
inline constexpr double kRootSiftScale = 255.0;

// RootSIFT as photos are matched with, and keyframes stored for that: 1,000 at most per image
// (on the survey model's 200 photos 1,000 placed what 1,500 did, in less time).
FeatureOptions RootSiftForPhotos();

// SLAM (tracking, loop closure, the vocabulary) takes ORB only: a one-line error otherwise.
bool CheckOrbFeatures(const FeatureOptions& options, std::string* error);

// Detects and describes features in a BGR or grey image; with a depth image (16-bit mm, same size,
// registered), each keypoint whose depth is valid gets its 3D point through `camera`. Pass an
// empty depth for a photo without depth.
Features ExtractFeatures(const cv::Mat& image, const cv::Mat& depth_mm, const Intrinsics& camera,
                         const FeatureOptions& options = FeatureOptions());

// The same for an image whose longer side exceeds `max_side_px`: features of a copy downscaled to
// it (colour by area, depth by nearest sample), keypoints at that scale, 3D points unchanged in
// meaning. What photos are matched against: a keyframe at the photo matcher's scale.
Features ExtractFeaturesAtMostOfSide(const cv::Mat& image, const cv::Mat& depth_mm,
                                     const Intrinsics& camera, int max_side_px,
                                     const FeatureOptions& options);

}  // namespace sightmap::slam
