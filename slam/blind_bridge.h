// Motions across a blind run: the keyframes a tracker placed on its motion model alone, because
// nothing registered for a second or more (a 1 Hz walker turning 35 degrees between frames).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Geometry>

namespace sightmap::slam {

// Which frame a walker keeps its velocity in across a blind run. A robot's camera goes where the
// robot heads, turning its velocity with it (kCamera); a hand-held camera looks about while the
// walker goes on (kWorld: the velocity is kept in the world, the turn is the head's).
enum class BridgeFrame { kCamera, kWorld };

// A measured motion between two consecutive keyframes and the time it took.
struct TimedMotion {
  Eigen::Isometry3d previous_from_cam = Eigen::Isometry3d::Identity();
  double dt_s = 0.0;  // > 0 [s]
};

// The motions of a run of blind steps (their durations `blind_dt_s`, oldest first, each > 0),
// bridged between the motion measured just before the run and the one measured just after it.
// Each step's velocity (LogSe3's translation and rotation vector per second, in the camera where
// the step starts) lies on the line between the two measured velocities, at the time of the
// step's middle between their middles. The motion model, placing the run as it happens, can only
// extrapolate the velocity before it: on the 1 Hz hand-held walks (seeds 11 and 23) its steps
// over blind seconds err by 0.19-0.20 m and 6 degrees at the median (p90 0.33-0.40 m, 39
// degrees) even from the true velocity before; the bridge from the true velocities on both
// sides by 0.08-0.09 m and 7-9 degrees (p90 0.19-0.23 m, 20-21 degrees). Throws InvalidArgument
// for durations that are not positive.
// With kWorld the translations are interpolated in the world (expressed in the camera where the
// run starts, through the bridged rotations), the rotations as with kCamera: from the true
// motions on both sides and the true rotation, the translation of a 1 Hz hand-held walk's blind
// step errs 26-28 mm at the median (p90 0.10-0.11 m), against 92-100 mm (p90 0.19 m) in the
// camera (seeds 1 and 7).
// `step_rotations`, when given (one per step), replaces a step's interpolated rotation where it
// holds one (measured otherwise, e.g. from the building's axes at both of its ends).
std::vector<Eigen::Isometry3d> BridgeBlindRun(
    const TimedMotion& before, const std::vector<double>& blind_dt_s, const TimedMotion& after,
    BridgeFrame frame = BridgeFrame::kCamera,
    const std::vector<std::optional<Eigen::Matrix3d>>& step_rotations = {});

}  // namespace sightmap::slam
