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
  // The alignment with a scale as well (Umeyama's Sim(3)): the scale that maps the estimate onto
  // the ground truth (1.01: the map came out 1% small) and the RMSE left after it. A map that is
  // uniformly too small is consistent with every loop, so loops cannot correct it; this tells it
  // apart from a bent one.
  double sim3_scale = 1.0;
  double sim3_ate_rmse_m = 0.0;
  // Matched pairs, oldest first, for plots: their timestamps, ground-truth and aligned estimated
  // positions.
  std::vector<TimestampNs> timestamps_ns;
  std::vector<Eigen::Vector3d> gt_positions;
  std::vector<Eigen::Vector3d> aligned_positions;
};

// Throws sightmap::Error when fewer than 3 poses match by timestamp (nothing to align).
TrajectoryError EvaluateTrajectory(const std::vector<StampedPose>& ground_truth,
                                   const std::vector<StampedPose>& estimate,
                                   const TrajectoryEvalOptions& options = TrajectoryEvalOptions());

// A stretch of the walk and the ATE of the poses in it.
struct ErrorStretch {
  double start_s = 0.0;  // since the first matched pose [s]
  double end_s = 0.0;
  int poses = 0;
  double mean_m = 0.0;
  double max_m = 0.0;
};

// The walk cut into consecutive stretches of window_s seconds from its first matched pose, the
// `count` with the largest mean error first: where a map's error comes from.
std::vector<ErrorStretch> WorstStretches(const TrajectoryError& error, double window_s, int count);

// How concentrated the error is: the share of the summed squared error that the worst `fraction`
// of poses (at least one) hold, and the RMSE of the others (a few isolated keyframes far off, or a
// map off everywhere).
struct ErrorConcentration {
  int worst_poses = 0;
  double worst_share = 0.0;
  double rest_rmse_m = 0.0;
};
ErrorConcentration ConcentrationOfError(const TrajectoryError& error, double fraction);

// Where a trajectory's error comes from, as `eval trajectory` and slam_benchmark report it: the
// three worst stretches of `stretch_s` seconds and the concentration in the worst 2% of poses.
struct ErrorSources {
  std::vector<ErrorStretch> stretches;
  ErrorConcentration concentration;
};
ErrorSources FindErrorSources(const TrajectoryError& error, double stretch_s = 10.0);

}  // namespace sightmap::slam
