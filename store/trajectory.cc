#include "store/trajectory.h"

namespace sightmap::store {

std::vector<StampedPose> ModelTrajectory(const Model& model, bool odometry) {
  std::vector<StampedPose> poses;
  for (const KeyframeInfo& keyframe : model.Keyframes()) {
    poses.push_back(
        {keyframe.timestamp_ns, odometry ? keyframe.odom_world_from_cam : keyframe.world_from_cam});
  }
  return poses;
}

}  // namespace sightmap::store
