// The building manager's walk (hand-held sensor) or a robot's drive through the scene's tour.
//
// The tour (Scene::tour) is a closed loop through every room; it is smoothed with a centripetal
// Catmull-Rom spline and walked at constant speed, lap after lap, so every place is revisited
// (loop closures). Session N starts at another tour point.
//  - handheld: 0.5 m/s with a slow +-10% pace change; head height drifting in [1.45, 1.65] m plus a
//    2.5 cm bob at the step frequency (1.8 Hz) and a 2 cm sideways sway at half of it; in 10 s
//    windows the operator turns (easing in and out) to look at a nearby appliance or, in the other
//    windows, at the wall 0.9-3.5 m away that is nearest 2.2 m (where the sensor measures well),
//    with a small left-right sweep on top; pitch stays within +-15 deg, roll within +-5 deg.
//  - robot: 0.4 m/s, camera at 0.75 m, level (no pitch or roll), heading along the smoothed path
//    and turning smoothly towards the same wall and appliance targets (a pan-tilt head).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "sim/scene.h"

namespace sightmap::sim {

enum class TrajectoryKind { kHandheld, kRobot };
TrajectoryKind ParseTrajectoryKind(const std::string& name);  // throws InvalidArgument
const char* ToString(TrajectoryKind kind);

struct TrajectoryOptions {
  TrajectoryKind kind = TrajectoryKind::kHandheld;
  double speed_mps = 0.0;  // walking speed [m/s]; 0 = 0.5 hand-held, 0.4 robot
  int session = 1;         // >= 1; moves the start along the tour
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

class Trajectory {
 public:
  Trajectory(const Scene& scene, const TrajectoryOptions& options);

  // The camera pose at time t [s] since the start (OpenCV camera frame, world z up).
  Eigen::Isometry3d WorldFromCam(double t_s) const;
  // Length of one lap of the smoothed tour [m].
  double lap_length_m() const { return lap_length_m_; }
  double speed_mps() const { return speed_mps_; }

 private:
  Eigen::Vector2d PositionAt(double s_m) const;  // arc length along the loop, wraps
  double DistanceAt(double t_s) const;

  TrajectoryOptions options_;
  std::vector<Eigen::Vector2d> polyline_;  // dense samples of one lap
  std::vector<double> arc_;                // cumulative arc length at each sample
  double lap_length_m_ = 0.0;
  double speed_mps_ = 0.5;
  double start_s_m_ = 0.0;
  double phases_[8] = {};
  // What the operator turns to look at during the window containing t (nullopt: nothing).
  std::optional<Eigen::Vector3d> LookTarget(double t_s, double eye_height_m) const;

  Scene scene_;                                // for the lines of sight to walls
  std::vector<Eigen::Vector3d> look_targets_;  // appliance points
};

// Camera orientation from heading (yaw about world z from +x), pitch (up positive) and roll
// (clockwise in the image positive) [rad].
Eigen::Matrix3d WorldFromCamRotation(double yaw, double pitch, double roll);

}  // namespace sightmap::sim
