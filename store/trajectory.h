// A model's keyframe trajectory; the TUM trajectory files it is written to and compared with are
// core/tum_format.h's.
#pragma once

#include <vector>

#include "core/rgbd_frame.h"
#include "core/tum_format.h"
#include "store/model.h"

namespace sightmap::store {

// The model's keyframes in id order: optimised poses, or the raw odometry.
std::vector<StampedPose> ModelTrajectory(const Model& model, bool odometry = false);

}  // namespace sightmap::store
