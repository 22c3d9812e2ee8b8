#include "slam/trajectory_eval.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <tuple>
#include <utility>

#include <Eigen/Geometry>

#include "core/check.h"
#include "core/rotation.h"
#include "slam/rigid_alignment.h"

namespace sightmap::slam {
namespace {

struct MatchedPose {
  TimestampNs timestamp_ns;
  Eigen::Isometry3d gt;
  Eigen::Isometry3d est;
};

// One-to-one association, as TUM's associate.py: every (estimate, ground truth) pair within
// `max_difference_ns` is a candidate, and the closest pairs are taken first, so no ground-truth
// pose is matched twice (an estimate denser than the ground truth would otherwise compare the
// same ground-truth pose with estimates taken at different times).
std::vector<MatchedPose> MatchByTimestamp(std::vector<StampedPose> ground_truth,
                                          const std::vector<StampedPose>& estimate,
                                          int64_t max_difference_ns) {
  const auto earlier = [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp_ns < b.timestamp_ns;
  };
  std::sort(ground_truth.begin(), ground_truth.end(), earlier);
  struct Candidate {
    int64_t difference;
    size_t est;
    size_t gt;
  };
  std::vector<Candidate> candidates;
  for (size_t e = 0; e < estimate.size(); ++e) {
    const TimestampNs t = estimate[e].timestamp_ns;
    StampedPose lowest;
    lowest.timestamp_ns = t < std::numeric_limits<TimestampNs>::min() + max_difference_ns
                              ? std::numeric_limits<TimestampNs>::min()
                              : t - max_difference_ns;
    for (auto it = std::lower_bound(ground_truth.begin(), ground_truth.end(), lowest, earlier);
         it != ground_truth.end(); ++it) {
      const int64_t difference = std::llabs(it->timestamp_ns - t);
      if (it->timestamp_ns > t && difference > max_difference_ns) break;
      if (difference <= max_difference_ns) {
        candidates.push_back({difference, e, static_cast<size_t>(it - ground_truth.begin())});
      }
    }
  }
  // Ties go to the earlier estimate, then the earlier ground truth, so the result is deterministic.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.difference, a.est, a.gt) < std::tie(b.difference, b.est, b.gt);
  });
  std::vector<bool> est_used(estimate.size(), false);
  std::vector<bool> gt_used(ground_truth.size(), false);
  std::vector<MatchedPose> matched;
  for (const Candidate& candidate : candidates) {
    if (est_used[candidate.est] || gt_used[candidate.gt]) continue;
    est_used[candidate.est] = gt_used[candidate.gt] = true;
    matched.push_back({estimate[candidate.est].timestamp_ns,
                       ground_truth[candidate.gt].world_from_cam,
                       estimate[candidate.est].world_from_cam});
  }
  std::sort(matched.begin(), matched.end(), [](const MatchedPose& a, const MatchedPose& b) {
    return a.timestamp_ns < b.timestamp_ns;
  });
  return matched;
}

// Mean drift over pairs (i, j) chosen by `next(i)`; returns {translation, rotation} per unit of
// `length(i, j)`.
template <typename NextFn, typename LengthFn>
std::pair<double, double> MeanDrift(const std::vector<MatchedPose>& poses, NextFn next,
                                    LengthFn length, int* pairs) {
  double translation = 0.0;
  double rotation = 0.0;
  *pairs = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const size_t j = next(i);
    if (j >= poses.size()) break;
    const double span = length(i, j);
    if (!(span > 0.0)) continue;
    const Eigen::Isometry3d gt_motion = poses[i].gt.inverse() * poses[j].gt;
    const Eigen::Isometry3d est_motion = poses[i].est.inverse() * poses[j].est;
    const Eigen::Isometry3d error = gt_motion.inverse() * est_motion;
    translation += error.translation().norm() / span;
    rotation += RotationAngleDeg(error.linear()) / span;
    ++*pairs;
  }
  if (*pairs == 0) return {0.0, 0.0};
  return {translation / *pairs, rotation / *pairs};
}

// Umeyama's similarity alignment of `est` onto `gt`: its scale and the RMSE left after it.
std::pair<double, double> SimilarityFit(const std::vector<Eigen::Vector3d>& est,
                                        const std::vector<Eigen::Vector3d>& gt) {
  Eigen::Matrix3Xd from(3, est.size());
  Eigen::Matrix3Xd to(3, gt.size());
  for (size_t i = 0; i < est.size(); ++i) {
    from.col(static_cast<Eigen::Index>(i)) = est[i];
    to.col(static_cast<Eigen::Index>(i)) = gt[i];
  }
  const Eigen::Matrix4d gt_from_est = Eigen::umeyama(from, to, true);
  const double scale = gt_from_est.topLeftCorner<3, 3>().determinant();
  const Eigen::Matrix3Xd moved =
      (gt_from_est.topLeftCorner<3, 3>() * from).colwise() + gt_from_est.topRightCorner<3, 1>();
  const double rmse = std::sqrt((moved - to).colwise().squaredNorm().mean());
  return {std::cbrt(scale), rmse};
}

std::vector<double> PoseErrors(const TrajectoryError& error) {
  std::vector<double> errors;
  for (size_t i = 0; i < error.gt_positions.size(); ++i) {
    errors.push_back((error.aligned_positions[i] - error.gt_positions[i]).norm());
  }
  return errors;
}

}  // namespace

std::vector<ErrorStretch> WorstStretches(const TrajectoryError& error, double window_s, int count) {
  SIGHTMAP_CHECK(window_s > 0.0 && count >= 0,
                 "WorstStretches needs a positive window and a count >= 0");
  const std::vector<double> errors = PoseErrors(error);
  // Keyed by the stretch's index: a short window over a long recording has few stretches with
  // poses in them, however many lie between.
  std::map<int64_t, ErrorStretch> by_index;
  for (size_t i = 0; i < errors.size(); ++i) {
    const double t = (error.timestamps_ns[i] - error.timestamps_ns.front()) * 1e-9;
    const auto index = static_cast<int64_t>(std::floor(t / window_s));
    ErrorStretch& stretch = by_index[index];
    stretch.start_s = index * window_s;
    stretch.end_s = (index + 1) * window_s;
    ++stretch.poses;
    stretch.mean_m += errors[i];
    stretch.max_m = std::max(stretch.max_m, errors[i]);
  }
  std::vector<ErrorStretch> stretches;
  for (auto& [index, stretch] : by_index) {
    stretch.mean_m /= stretch.poses;
    stretches.push_back(stretch);
  }
  std::sort(stretches.begin(), stretches.end(), [](const ErrorStretch& a, const ErrorStretch& b) {
    return a.mean_m > b.mean_m || (a.mean_m == b.mean_m && a.start_s < b.start_s);
  });
  if (static_cast<int>(stretches.size()) > count) stretches.resize(static_cast<size_t>(count));
  return stretches;
}

ErrorConcentration ConcentrationOfError(const TrajectoryError& error, double fraction) {
  SIGHTMAP_CHECK(fraction >= 0.0 && fraction <= 1.0, "the fraction of poses must be in [0, 1]");
  std::vector<double> squared = PoseErrors(error);
  for (double& e : squared) e *= e;
  std::sort(squared.begin(), squared.end(), std::greater<>());
  ErrorConcentration result;
  if (squared.empty()) return result;
  // At least one pose when a fraction is asked for, so short walks say something too.
  result.worst_poses = static_cast<int>(std::lround(fraction * squared.size()));
  if (fraction > 0.0) result.worst_poses = std::max(result.worst_poses, 1);
  double worst = 0.0;
  double total = 0.0;
  for (size_t i = 0; i < squared.size(); ++i) {
    total += squared[i];
    if (static_cast<int>(i) < result.worst_poses) worst += squared[i];
  }
  const size_t rest = squared.size() - static_cast<size_t>(result.worst_poses);
  result.worst_share = total > 0.0 ? worst / total : 0.0;
  result.rest_rmse_m = rest > 0 ? std::sqrt((total - worst) / rest) : 0.0;
  return result;
}

ErrorSources FindErrorSources(const TrajectoryError& error, double stretch_s) {
  constexpr int kWorstStretches = 3;
  constexpr double kWorstPoseFraction = 0.02;
  return {WorstStretches(error, stretch_s, kWorstStretches),
          ConcentrationOfError(error, kWorstPoseFraction)};
}

bool TrajectoryEvalOptions::Check(std::string* error) const {
  if (max_time_difference_ns < 0 || !(rpe_distance_m > 0.0) || !(rpe_interval_s > 0.0)) {
    if (error) *error = "time difference must be >= 0 and RPE distance and interval positive";
    return false;
  }
  return true;
}

TrajectoryError EvaluateTrajectory(const std::vector<StampedPose>& ground_truth,
                                   const std::vector<StampedPose>& estimate,
                                   const TrajectoryEvalOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const std::vector<MatchedPose> poses =
      MatchByTimestamp(ground_truth, estimate, options.max_time_difference_ns);
  SIGHTMAP_CHECK(poses.size() >= 3, "only " << poses.size() << " of " << estimate.size()
                                            << " estimated poses have a ground-truth pose within "
                                            << options.max_time_difference_ns * 1e-6
                                            << " ms: check that both files use the same clock");
  TrajectoryError result;
  result.matched_poses = static_cast<int>(poses.size());

  std::vector<Eigen::Vector3d> est_positions;
  for (const MatchedPose& pose : poses) {
    result.timestamps_ns.push_back(pose.timestamp_ns);
    est_positions.push_back(pose.est.translation());
    result.gt_positions.push_back(pose.gt.translation());
  }
  SIGHTMAP_CHECK(AlignRigid(est_positions, result.gt_positions, {}, &result.gt_from_est),
                 "cannot align the trajectories: the matched positions are (nearly) collinear");

  std::vector<double> errors;
  double squared = 0.0;
  for (size_t i = 0; i < poses.size(); ++i) {
    result.aligned_positions.push_back(result.gt_from_est * est_positions[i]);
    const double error = (result.aligned_positions[i] - result.gt_positions[i]).norm();
    errors.push_back(error);
    squared += error * error;
    result.ate_mean_m += error;
    result.ate_max_m = std::max(result.ate_max_m, error);
  }
  result.ate_rmse_m = std::sqrt(squared / errors.size());
  std::tie(result.sim3_scale, result.sim3_ate_rmse_m) =
      SimilarityFit(est_positions, result.gt_positions);
  result.ate_mean_m /= errors.size();
  // The median of an even count is the mean of the two middle errors.
  const size_t middle = errors.size() / 2;
  std::nth_element(errors.begin(), errors.begin() + middle, errors.end());
  result.ate_median_m = errors[middle];
  if (errors.size() % 2 == 0) {
    result.ate_median_m =
        0.5 * (result.ate_median_m + *std::max_element(errors.begin(), errors.begin() + middle));
  }

  // Distance travelled along the ground truth, for the per-metre RPE.
  std::vector<double> travelled(poses.size(), 0.0);
  for (size_t i = 1; i < poses.size(); ++i) {
    travelled[i] =
        travelled[i - 1] + (poses[i].gt.translation() - poses[i - 1].gt.translation()).norm();
  }
  const auto by_distance = [&](size_t i) {
    return static_cast<size_t>(std::lower_bound(travelled.begin() + static_cast<std::ptrdiff_t>(i),
                                                travelled.end(),
                                                travelled[i] + options.rpe_distance_m) -
                               travelled.begin());
  };
  const auto distance = [&](size_t i, size_t j) { return travelled[j] - travelled[i]; };
  std::tie(result.rpe_trans_per_m, result.rpe_rot_deg_per_m) =
      MeanDrift(poses, by_distance, distance, &result.rpe_pairs_distance);

  const auto interval_ns = static_cast<int64_t>(options.rpe_interval_s * 1e9);
  const auto by_time = [&](size_t i) {
    size_t j = i;
    while (j < poses.size() && poses[j].timestamp_ns - poses[i].timestamp_ns < interval_ns) ++j;
    return j;
  };
  const auto seconds = [&](size_t i, size_t j) {
    return (poses[j].timestamp_ns - poses[i].timestamp_ns) * 1e-9;
  };
  std::tie(result.rpe_trans_per_s, result.rpe_rot_deg_per_s) =
      MeanDrift(poses, by_time, seconds, &result.rpe_pairs_time);
  return result;
}

}  // namespace sightmap::slam
