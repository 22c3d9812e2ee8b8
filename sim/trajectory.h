// The building manager's walk (hand-held sensor) or a robot's drive through the scene's tour.
//
// The tour (Scene::tour) is a closed loop through every room; it is smoothed with a centripetal
// Catmull-Rom spline and walked at constant speed, lap after lap, so every place is revisited
// (loop closures). Session N starts at another tour point.
//  - handheld: 0.5 m/s with a slow +-10% pace change; head height drifting in [1.45, 1.65] m plus a
//    2.5 cm bob at the step frequency (1.8 Hz) and a 2 cm sideways sway at half of it; in 10 s
//    windows the operator turns (easing in and out) to look at a nearby appliance or, in the other
//    windows, in the direction the sensor maps best (most of the view within its range, on
//    furniture and posters rather than bare walls; the centre 1.6-3.8 m away, preferably 3 m),
//    with a small left-right sweep on top; pitch stays within +-15 deg, roll within +-5 deg.
//  - robot: 0.4 m/s, camera at 0.75 m, level (no pitch or roll), driving along the smoothed path
//    while its pan-tilt head keeps the camera on the same wall and appliance targets, one per
//    window, panning smoothly to the next over the window's last quarter (facing down a corridor
//    or a 10 m room at 0.75 m, a Kinect sees mostly beyond its 4.5 m range).
//  - survey: the hand-held sensor carried along a survey plan (sim/survey.h) instead of the tour:
//    the walker stops at each appliance's standpoints (dwell_s, looking at it; the camera tilts up
//    to 35 deg at ceiling lights) and walks between them at 0.3 m/s, speeding up and slowing down
//    at 0.5 m/s^2, looking ahead and turning to the next appliance over the last 2 s of each leg;
//    height, bob, sway and roll as hand-held. One lap covers every appliance; laps repeat.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "sim/scene.h"
#include "sim/survey.h"

namespace sightmap::sim {

enum class TrajectoryKind { kHandheld, kRobot, kSurvey };
TrajectoryKind ParseTrajectoryKind(const std::string& name);  // throws InvalidArgument
const char* ToString(TrajectoryKind kind);

struct TrajectoryOptions {
  TrajectoryKind kind = TrajectoryKind::kHandheld;
  // Walking speed [m/s]; 0 = 0.5 hand-held, 0.4 robot, 0.3 survey (a careful capture: the paper's
  // operator took 18 minutes for an 80 m^2 lab).
  double speed_mps = 0.0;
  // Fastest turn of the heading [deg/s]; 0 = 35 hand-held, 30 robot. A person mapping while
  // walking turns about that fast (frames a second apart are up to ~0.5 m and 30-35 deg apart);
  // the camera follows what the walker wants to look at no faster than this. Before this limit
  // the walk turned up to 170 deg between two 1 Hz frames, which no registration can bridge.
  double max_turn_rate_dps = 0.0;
  int session = 1;  // >= 1; moves the start along the tour
  uint64_t seed = 1;
  // Survey only: seconds standing at each standpoint, and the plan's options.
  double dwell_s = 5.0;
  SurveyOptions survey;

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
  // Survey: seconds for one lap, and the plan walked (nullopt for the other kinds).
  double lap_duration_s() const;
  const std::optional<SurveyPlan>& survey_plan() const { return survey_plan_; }

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

  // The survey's lap as legs in time: standing at a stop (s constant) or walking to the next.
  struct SurveyLeg {
    double t0_s = 0.0, duration_s = 0.0;
    // Walking legs: walking time / duration_s (< 1 when stretched to the 2 s a turn between two
    // close standpoints takes); 0 standing.
    double pace = 0.0;
    double s0_m = 0.0, length_m = 0.0;
    std::optional<Eigen::Vector3d> target;       // standing: looked at; walking: the previous one
    std::optional<Eigen::Vector3d> next_target;  // walking: the one at the leg's end
  };
  std::optional<SurveyPlan> survey_plan_;
  std::vector<SurveyLeg> survey_legs_;
  double survey_lap_s_ = 0.0;
  double survey_start_s_ = 0.0;
  void BuildSurveyLegs();
  const SurveyLeg& SurveyLegAt(double t_s, double* t_in_leg_s) const;
  double SurveyDistance(const SurveyLeg& leg, double t_in_leg_s) const;  // arc length [m]
  // What the operator turns to look at during the window containing t (nullopt: nothing);
  // chosen once per window and eye height, then cached.
  std::optional<Eigen::Vector3d> LookTarget(double t_s, double eye_height_m) const;
  std::optional<Eigen::Vector3d> ChooseLookTarget(int64_t window_index, double eye_height_m) const;

  Scene scene_;                                // for the lines of sight to walls
  std::vector<Eigen::Vector3d> look_targets_;  // appliance points
  struct LookCache {
    std::mutex mutex;
    std::map<std::pair<int64_t, int>, std::optional<Eigen::Vector3d>> targets;
  };
  std::shared_ptr<LookCache> look_cache_;

  // Position and attitude the walker aims for at t; the heading actually taken is LimitedYaw.
  struct Attitude {
    Eigen::Vector3d position;
    double yaw = 0.0;
    double pitch = 0.0;
    double roll = 0.0;
  };
  Attitude DesiredAt(double t_s) const;
  // A person's body at t (hand-held and survey): eye height drifting in [1.47, 1.63] m plus the
  // step's 2.5 cm bob, the 2 cm sideways sway of the steps off `position` and the roll; `stepping`
  // in [0, 1] scales what the steps add (0 standing, 1 walking).
  struct Gait {
    double height = 0.0;
    Eigen::Vector2d swayed = Eigen::Vector2d::Zero();
    double roll = 0.0;
  };
  Gait GaitAt(double t_s, const Eigen::Vector2d& position, double path_yaw, double stepping) const;
  Attitude SurveyDesiredAt(double t_s) const;
  // Walking, the operator keeps the sensor's view open: `yaw`, or the nearest heading (in 10 deg
  // steps, up to 120 deg away) not aimed at a surface within 1.2 m, where the sensor measures
  // nothing below 0.5 m and the image is a blur of one poster.
  double OpenYaw(const Eigen::Vector3d& eye, double yaw) const;
  double LimitedYaw(double t_s) const;
  double turn_rate_rad_s_ = 0.0;
  struct YawCache {
    std::mutex mutex;
    std::vector<double> samples;  // unwrapped heading at a fixed step from t = 0 [rad]
  };
  std::shared_ptr<YawCache> yaw_cache_;  // shared by copies: the headings are deterministic
};

// Camera orientation from heading (yaw about world z from +x), pitch (up positive) and roll
// (clockwise in the image positive) [rad].
Eigen::Matrix3d WorldFromCamRotation(double yaw, double pitch, double roll);

}  // namespace sightmap::sim
