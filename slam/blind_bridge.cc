#include "slam/blind_bridge.h"

#include <cmath>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::slam {

std::vector<Eigen::Isometry3d> BridgeBlindRun(
    const TimedMotion& before, const std::vector<double>& blind_dt_s, const TimedMotion& after,
    BridgeFrame frame, const std::vector<std::optional<Eigen::Matrix3d>>& step_rotations) {
  if (!step_rotations.empty() && step_rotations.size() != blind_dt_s.size()) {
    SIGHTMAP_THROW(InvalidArgument, "bridging a blind run needs one rotation entry per step");
  }
  const auto positive = [](double s) { return s > 0.0 && std::isfinite(s); };
  if (!positive(before.dt_s) || !positive(after.dt_s)) {
    SIGHTMAP_THROW(InvalidArgument,
                   "bridging a blind run needs measured motions of positive duration");
  }
  double run_s = 0.0;
  for (double dt_s : blind_dt_s) {
    if (!positive(dt_s)) SIGHTMAP_THROW(InvalidArgument, "a blind step needs a positive duration");
    run_s += dt_s;
  }
  const Eigen::Matrix<double, 6, 1> velocity_before =
      LogSe3(before.previous_from_cam) / before.dt_s;
  const Eigen::Matrix<double, 6, 1> velocity_after = LogSe3(after.previous_from_cam) / after.dt_s;
  // Times from the middle of the motion before the run to the middle of the one after it.
  const double span_s = 0.5 * before.dt_s + run_s + 0.5 * after.dt_s;
  // Each step's weight of the velocity after the run: its middle's time along the span.
  std::vector<double> weights;
  weights.reserve(blind_dt_s.size());
  double start_s = 0.5 * before.dt_s;
  for (double dt_s : blind_dt_s) {
    weights.push_back((start_s + 0.5 * dt_s) / span_s);
    start_s += dt_s;
  }
  std::vector<Eigen::Isometry3d> motions;
  motions.reserve(blind_dt_s.size());
  for (size_t k = 0; k < blind_dt_s.size(); ++k) {
    const double w = weights[k];
    const Eigen::Matrix<double, 6, 1> velocity = (1.0 - w) * velocity_before + w * velocity_after;
    motions.push_back(ExpSe3(velocity * blind_dt_s[k]));
    if (!step_rotations.empty() && step_rotations[k]) motions.back().linear() = *step_rotations[k];
  }
  if (frame == BridgeFrame::kCamera) return motions;
  // The velocities on both sides in the camera where the run starts (R: the run's rotations from
  // there), and each step's translation by their interpolation, in the camera where it starts.
  Eigen::Matrix3d run_start_from_cam = Eigen::Matrix3d::Identity();
  for (const Eigen::Isometry3d& motion : motions) run_start_from_cam *= motion.linear();
  const Eigen::Vector3d before_mps = before.previous_from_cam.linear().transpose() *
                                     before.previous_from_cam.translation() / before.dt_s;
  const Eigen::Vector3d after_mps =
      run_start_from_cam * after.previous_from_cam.translation() / after.dt_s;
  Eigen::Matrix3d step_start = Eigen::Matrix3d::Identity();
  for (size_t k = 0; k < motions.size(); ++k) {
    const double w = weights[k];
    motions[k].translation() =
        step_start.transpose() * (((1.0 - w) * before_mps + w * after_mps) * blind_dt_s[k]);
    step_start *= motions[k].linear();
  }
  return motions;
}

}  // namespace sightmap::slam
