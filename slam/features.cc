#include "slam/features.h"

#include <algorithm>
#include <cmath>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"

namespace sightmap::slam {
namespace {

cv::Ptr<cv::Feature2D> MakeDetector(const FeatureOptions& options, int max_features) {
  if (options.type == FeatureOptions::Type::kSift) {
    // Every keypoint SIFT finds, then the grid keeps max_features of them spread out.
    return cv::SIFT::create(/*nfeatures=*/0, /*nOctaveLayers=*/3, options.sift_contrast_threshold);
  }
  return cv::ORB::create(max_features, static_cast<float>(options.orb_scale_factor),
                         options.orb_levels, /*edgeThreshold=*/31, /*firstLevel=*/0,
                         /*WTA_K=*/2, cv::ORB::HARRIS_SCORE, /*patchSize=*/31,
                         options.orb_fast_threshold);
}

// Keeps the strongest keypoints of each grid cell (an equal share per cell, and what cells with
// fewer corners leave over goes to the strongest of the rest), so features cover the image.
std::vector<cv::KeyPoint> SpreadOverGrid(std::vector<cv::KeyPoint> keypoints, cv::Size size,
                                         const FeatureOptions& options) {
  if (static_cast<int>(keypoints.size()) <= options.max_features) return keypoints;
  const int cells = options.grid_cols * options.grid_rows;
  std::vector<std::vector<cv::KeyPoint>> by_cell(cells);
  for (const cv::KeyPoint& keypoint : keypoints) {
    const int col = std::clamp(static_cast<int>(keypoint.pt.x * options.grid_cols / size.width), 0,
                               options.grid_cols - 1);
    const int row = std::clamp(static_cast<int>(keypoint.pt.y * options.grid_rows / size.height), 0,
                               options.grid_rows - 1);
    by_cell[row * options.grid_cols + col].push_back(keypoint);
  }
  const auto stronger = [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    return a.response > b.response;
  };
  const size_t share = static_cast<size_t>(options.max_features / cells);
  std::vector<cv::KeyPoint> kept;
  std::vector<cv::KeyPoint> rest;
  for (std::vector<cv::KeyPoint>& cell : by_cell) {
    std::sort(cell.begin(), cell.end(), stronger);
    const size_t take = std::min(share, cell.size());
    kept.insert(kept.end(), cell.begin(), cell.begin() + static_cast<std::ptrdiff_t>(take));
    rest.insert(rest.end(), cell.begin() + static_cast<std::ptrdiff_t>(take), cell.end());
  }
  std::sort(rest.begin(), rest.end(), stronger);
  const size_t missing = static_cast<size_t>(options.max_features) - kept.size();
  kept.insert(kept.end(), rest.begin(),
              rest.begin() + static_cast<std::ptrdiff_t>(std::min(missing, rest.size())));
  return kept;
}

// SIFT rows (CV_32F) to RootSIFT bytes: each row L1-normalised, square-rooted (unit L2 norm), and
// scaled by kRootSiftScale.
cv::Mat ToRootSiftBytes(const cv::Mat& sift) {
  cv::Mat bytes(sift.rows, sift.cols, CV_8U);
  for (int r = 0; r < sift.rows; ++r) {
    const float* in = sift.ptr<float>(r);
    double sum = 0.0;
    for (int c = 0; c < sift.cols; ++c) sum += std::abs(in[c]);
    uint8_t* out = bytes.ptr<uint8_t>(r);
    for (int c = 0; c < sift.cols; ++c) {
      const double root = sum > 0.0 ? std::sqrt(std::abs(in[c]) / sum) : 0.0;
      out[c] = cv::saturate_cast<uint8_t>(root * kRootSiftScale);
    }
  }
  return bytes;
}

}  // namespace

FeatureOptions RootSiftForPhotos() {
  FeatureOptions options;
  options.type = FeatureOptions::Type::kSift;
  options.max_features = 1000;
  return options;
}

bool CheckOrbFeatures(const FeatureOptions& options, std::string* error) {
  if (!options.Check(error)) return false;
  if (options.type == FeatureOptions::Type::kOrb) return true;
  if (error) {
    *error =
        "SLAM takes ORB features (type \"orb\"): tracking, loop closure and the vocabulary "
        "match binary descriptors; SIFT is for photos";
  }
  return false;
}

bool FeatureOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (max_features <= 0) return fail("max_features must be positive");
  if (grid_cols <= 0 || grid_rows <= 0) return fail("grid_cols and grid_rows must be positive");
  if (orb_levels <= 0 || !(orb_scale_factor > 1.0)) {
    return fail("orb_levels must be positive and orb_scale_factor above 1");
  }
  if (orb_fast_threshold <= 0) return fail("orb_fast_threshold must be positive");
  if (!(sift_contrast_threshold > 0.0)) return fail("sift_contrast_threshold must be positive");
  if (!(min_depth_m > 0.0) || !(max_depth_m > min_depth_m)) {
    return fail("need 0 < min_depth_m < max_depth_m");
  }
  if (depth_window_radius_px < 0 || !(depth_edge_ratio > 0.0)) {
    return fail("depth_window_radius_px must be >= 0 and depth_edge_ratio positive");
  }
  return true;
}

Features ExtractFeatures(const cv::Mat& image, const cv::Mat& depth_mm, const Intrinsics& camera,
                         const FeatureOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!image.empty() && (image.type() == CV_8UC3 || image.type() == CV_8UC1),
                 "features need an 8-bit BGR or grey image");
  SIGHTMAP_CHECK(
      depth_mm.empty() || (depth_mm.type() == CV_16UC1 && depth_mm.size() == image.size()),
      "depth for features must be 16-bit millimetres of the image's size");
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else {
    grey = image;
  }

  // Detect more than needed, then keep a spread-out subset and describe only those.
  const cv::Ptr<cv::Feature2D> detector = MakeDetector(options, options.max_features * 3);
  std::vector<cv::KeyPoint> candidates;
  detector->detect(grey, candidates);
  Features features;
  features.keypoints = SpreadOverGrid(std::move(candidates), grey.size(), options);
  detector->compute(grey, features.keypoints, features.descriptors);
  if (options.type == FeatureOptions::Type::kSift) {
    features.descriptors = ToRootSiftBytes(features.descriptors);
  }

  features.points_cam.assign(features.keypoints.size(), Eigen::Vector3d::Zero());
  features.has_point.assign(features.keypoints.size(), false);
  if (depth_mm.empty()) return features;
  const int radius = options.depth_window_radius_px;
  for (size_t i = 0; i < features.keypoints.size(); ++i) {
    const cv::Point2f& pt = features.keypoints[i].pt;
    const int u = static_cast<int>(std::lround(pt.x));
    const int v = static_cast<int>(std::lround(pt.y));
    if (u < radius || v < radius || u >= depth_mm.cols - radius || v >= depth_mm.rows - radius) {
      continue;
    }
    const double z = depth_mm.at<uint16_t>(v, u) * 1e-3;
    if (z < options.min_depth_m || z > options.max_depth_m) continue;
    double lowest;
    double highest;
    const cv::Mat window =
        depth_mm(cv::Rect(u - radius, v - radius, 2 * radius + 1, 2 * radius + 1));
    cv::minMaxLoc(window, &lowest, &highest, nullptr, nullptr, window > 0);
    if ((highest - lowest) * 1e-3 > options.depth_edge_ratio * z) continue;
    features.points_cam[i] = camera.Unproject(pt.x, pt.y, z);
    features.has_point[i] = true;
  }
  return features;
}

Features ExtractFeaturesAtMostOfSide(const cv::Mat& image, const cv::Mat& depth_mm,
                                     const Intrinsics& camera, int max_side_px,
                                     const FeatureOptions& options) {
  SIGHTMAP_CHECK(max_side_px > 0, "features need a positive image side, not " << max_side_px);
  const cv::Size size = SizeAtMostOfSide(image.size(), max_side_px);
  if (size == image.size()) return ExtractFeatures(image, depth_mm, camera, options);
  cv::Mat small_image;
  cv::resize(image, small_image, size, 0.0, 0.0, cv::INTER_AREA);
  cv::Mat small_depth;
  if (!depth_mm.empty()) cv::resize(depth_mm, small_depth, size, 0.0, 0.0, cv::INTER_NEAREST);
  return ExtractFeatures(small_image, small_depth, camera.Scaled(size.width, size.height), options);
}

namespace {
const std::pair<FeatureOptions::Type, const char*> kFeatureTypeNames[] = {
    {FeatureOptions::Type::kOrb, "orb"}, {FeatureOptions::Type::kSift, "sift"}};
}  // namespace

void to_json(nlohmann::json& json, const FeatureOptions::Type& type) {
  options_json::WriteEnum(json, type, kFeatureTypeNames);
}
void from_json(const nlohmann::json& json, FeatureOptions::Type& type) {
  options_json::ReadEnum(json, type, kFeatureTypeNames);
}

SIGHTMAP_OPTIONS_JSON(FeatureOptions, type, max_features, grid_cols, grid_rows, orb_levels,
                      orb_scale_factor, orb_fast_threshold, sift_contrast_threshold, min_depth_m,
                      max_depth_m, depth_window_radius_px, depth_edge_ratio)

}  // namespace sightmap::slam
