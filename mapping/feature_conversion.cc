#include "mapping/feature_conversion.h"

#include <cmath>
#include <limits>

#include "core/check.h"

namespace sightmap::mapping {

KeyframeFeatures ToStoreFeatures(const Features& features) {
  SIGHTMAP_CHECK(
      features.points_cam.size() == features.size() && features.has_point.size() == features.size(),
      "inconsistent features: " << features.size() << " keypoints, " << features.points_cam.size()
                                << " points");
  KeyframeFeatures stored;
  stored.keypoints = features.keypoints;
  stored.descriptors = features.descriptors;
  stored.cam_points.reserve(features.size());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = 0; i < features.size(); ++i) {
    stored.cam_points.push_back(features.has_point[i]
                                    ? Eigen::Vector3f(features.points_cam[i].cast<float>())
                                    : Eigen::Vector3f(nan, nan, nan));
  }
  return stored;
}

Features FromStoreFeatures(const KeyframeFeatures& stored) {
  SIGHTMAP_CHECK(stored.cam_points.size() == stored.keypoints.size() &&
                     stored.descriptors.rows == static_cast<int>(stored.keypoints.size()),
                 "a stored keyframe's features are inconsistent: "
                     << stored.keypoints.size() << " keypoints, " << stored.cam_points.size()
                     << " points, " << stored.descriptors.rows << " descriptors");
  Features features;
  features.keypoints = stored.keypoints;
  features.descriptors = stored.descriptors;
  features.points_cam.reserve(stored.keypoints.size());
  features.has_point.reserve(stored.keypoints.size());
  for (const Eigen::Vector3f& point : stored.cam_points) {
    const bool valid = point.allFinite();
    features.has_point.push_back(valid);
    features.points_cam.push_back(valid ? Eigen::Vector3d(point.cast<double>())
                                        : Eigen::Vector3d::Zero());
  }
  return features;
}

}  // namespace sightmap::mapping
