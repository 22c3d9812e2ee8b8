#include "core/features.h"

#include <algorithm>

namespace sightmap {

size_t Features::NumPoints() const {
  return static_cast<size_t>(std::count(has_point.begin(), has_point.end(), true));
}

bool Features::PointsMatchKeypoints() const {
  return points_cam.size() == has_point.size() &&
         (points_cam.empty() || points_cam.size() == keypoints.size());
}

bool Features::IsConsistent() const {
  return descriptors.rows == static_cast<int>(keypoints.size()) && PointsMatchKeypoints();
}

}  // namespace sightmap
