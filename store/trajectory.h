// Trajectories in the TUM RGB-D format: `timestamp tx ty tz qx qy qz qw` per line, timestamp in
// seconds, pose world_from_cam; lines starting with '#' are comments.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/rgbd_frame.h"
#include "store/model.h"

namespace sightmap {

// Timestamps are written with nanosecond digits and parsed without going through a double, so a
// round trip is exact.
void WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses);
std::vector<StampedPose> ReadTumTrajectory(const std::string& path);

// The model's keyframes in id order: optimised poses, or the raw odometry.
std::vector<StampedPose> ModelTrajectory(const Model& model, bool odometry = false);

}  // namespace sightmap
