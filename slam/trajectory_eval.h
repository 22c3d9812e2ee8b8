// Trajectory accuracy against ground truth (ARCHITECTURE.md, "Measuring it"): ATE after an SE(3)
// Horn/Umeyama alignment, and RPE as drift per metre travelled and per second.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/rgbd_frame.h"

namespace sightmap::slam {

struct TrajectoryEvalOptions {
  // Estimated and ground-truth poses are matched one-to-one, closest timestamps first, when no
  // further apart than this [ns].
  int64_t max_time_difference_ns = 20'000'000;
  // RPE compares motions over this distance along the ground-truth path [m] ...
  double rpe_distance_m = 1.0;
  // ... and over this time [s].
  double rpe_interval_s = 1.0;

  bool Check(std::string* error) const;
};

struct TrajectoryError {
  int matched_poses = 0;
  // Absolute trajectory error after alignment [m].
  double ate_rmse_m = 0.0;
  double ate_mean_m = 0.0;
  double ate_median_m = 0.0;
  double ate_max_m = 0.0;
  // Relative pose error: mean translation [m per m] and rotation [deg per m] drift over
  // rpe_distance_m, and per second over rpe_interval_s; 0 when the trajectory is too short.
  double rpe_trans_per_m = 0.0;
  double rpe_rot_deg_per_m = 0.0;
  double rpe_trans_per_s = 0.0;
  double rpe_rot_deg_per_s = 0.0;
  int rpe_pairs_distance = 0;
  int rpe_pairs_time = 0;
  // The alignment applied to the estimate: gt_world_from_est_world.
  Eigen::Isometry3d gt_from_est = Eigen::Isometry3d::Identity();
  // Matched pairs, for plots: ground-truth and aligned estimated positions.
  std::vector<Eigen::Vector3d> gt_positions;
  std::vector<Eigen::Vector3d> aligned_positions;
};

// Throws sightmap::Error when fewer than 3 poses match by timestamp (nothing to align).
TrajectoryError EvaluateTrajectory(const std::vector<StampedPose>& ground_truth,
                                   const std::vector<StampedPose>& estimate,
                                   const TrajectoryEvalOptions& options = TrajectoryEvalOptions());

}  // namespace sightmap::slam
