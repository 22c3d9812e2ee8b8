#include "slam/blind_bridge.h"

#include <cmath>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::slam {

std::vector<Eigen::Isometry3d> BridgeBlindRun(const TimedMotion& before,
                                              const std::vector<double>& blind_dt_s,
                                              const TimedMotion& after) {
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
  std::vector<Eigen::Isometry3d> motions;
  motions.reserve(blind_dt_s.size());
  double start_s = 0.5 * before.dt_s;
  for (double dt_s : blind_dt_s) {
    const double w = (start_s + 0.5 * dt_s) / span_s;
    const Eigen::Matrix<double, 6, 1> velocity = (1.0 - w) * velocity_before + w * velocity_after;
    motions.push_back(ExpSe3(velocity * dt_s));
    start_s += dt_s;
  }
  return motions;
}

}  // namespace sightmap::slam
