#include "core/features.h"

#include <algorithm>

namespace sightmap {

size_t Features::NumPoints() const {
  return static_cast<size_t>(std::count(has_point.begin(), has_point.end(), true));
}

bool Features::IsConsistent() const {
  const bool descriptors_match = descriptors.rows == static_cast<int>(keypoints.size()) ||
                                 (keypoints.empty() && descriptors.empty());
  const bool points_match = points_cam.size() == has_point.size() &&
                            (points_cam.empty() || points_cam.size() == keypoints.size());
  return descriptors_match && points_match;
}

}  // namespace sightmap
