// Synthetic keyframes with real image content and consistent geometry, so store tests, the
// benchmark and CLI tests can build models without a camera or the SLAM layer.
#pragma once

#include <cstdint>

#include "store/model.h"

namespace sightmap::store {

struct SyntheticKeyframeOptions {
  int width = 640;               // [px]
  int height = 480;              // [px]
  int num_features = 1000;       // keypoints with 32-byte (ORB-sized) descriptors
  double wall_distance_m = 2.0;  // the camera looks at a wall this far along its z axis [m]
  double step_m = 0.1;           // camera moves along world x by this per index [m]

  bool Check(std::string* error) const;
};

// Keyframe `index` of a camera sliding sideways in front of a textured wall: world_from_cam is a
// translation by index * step_m along x, odometry equals it, depth sees the wall at
// wall_distance_m. The features' 3D points lie on the wall. No links are set.
KeyframeRecord MakeSyntheticKeyframe(SessionId session, int index,
                                     const SyntheticKeyframeOptions& options = {});

// Intrinsics of the synthetic camera (a 640x480 Kinect-like field of view, scaled).
Intrinsics SyntheticIntrinsics(int width, int height);

}  // namespace sightmap::store
