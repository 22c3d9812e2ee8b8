#include "sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/check.h"
#include "core/rotation.h"
#include "sim/random.h"

namespace sightmap::sim {
namespace {

double WrapAngle(double a) {
  while (a > kPi) a -= 2 * kPi;
  while (a < -kPi) a += 2 * kPi;
  return a;
}

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

// Centripetal Catmull-Rom between p1 and p2 (alpha = 0.5 avoids loops and cusps at sharp turns).
Eigen::Vector2d CatmullRom(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1,
                           const Eigen::Vector2d& p2, const Eigen::Vector2d& p3, double t) {
  auto knot = [](double ti, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return ti + std::sqrt(std::max((b - a).norm(), 1e-6));
  };
  const double t0 = 0.0, t1 = knot(t0, p0, p1), t2 = knot(t1, p1, p2), t3 = knot(t2, p2, p3);
  const double tt = t1 + t * (t2 - t1);
  const Eigen::Vector2d a1 = (t1 - tt) / (t1 - t0) * p0 + (tt - t0) / (t1 - t0) * p1;
  const Eigen::Vector2d a2 = (t2 - tt) / (t2 - t1) * p1 + (tt - t1) / (t2 - t1) * p2;
  const Eigen::Vector2d a3 = (t3 - tt) / (t3 - t2) * p2 + (tt - t2) / (t3 - t2) * p3;
  const Eigen::Vector2d b1 = (t2 - tt) / (t2 - t0) * a1 + (tt - t0) / (t2 - t0) * a2;
  const Eigen::Vector2d b2 = (t3 - tt) / (t3 - t1) * a2 + (tt - t1) / (t3 - t1) * a3;
  return (t2 - tt) / (t2 - t1) * b1 + (tt - t1) / (t2 - t1) * b2;
}

}  // namespace

TrajectoryKind ParseTrajectoryKind(const std::string& name) {
  if (name == "handheld") return TrajectoryKind::kHandheld;
  if (name == "robot") return TrajectoryKind::kRobot;
  if (name == "survey") return TrajectoryKind::kSurvey;
  SIGHTMAP_THROW(InvalidArgument,
                 "unknown trajectory '" << name << "': use handheld, robot or survey");
}

const char* ToString(TrajectoryKind kind) {
  switch (kind) {
    case TrajectoryKind::kRobot:
      return "robot";
    case TrajectoryKind::kSurvey:
      return "survey";
    case TrajectoryKind::kHandheld:
      break;
  }
  return "handheld";
}

bool TrajectoryOptions::Check(std::string* error) const {
  if (max_turn_rate_dps < 0.0 || max_turn_rate_dps > 360.0) {
    *error = "max_turn_rate_dps must be in [0, 360] (0 = the kind's default)";
    return false;
  }
  if (speed_mps < 0.0 || speed_mps > 3.0) {
    *error = "speed_mps must be in [0, 3] (0 = the kind's default)";
    return false;
  }
  if (session < 1) {
    *error = "session must be >= 1";
    return false;
  }
  if (dwell_s < 0.0 || dwell_s > 60.0) {
    *error = "dwell_s must be in [0, 60]";
    return false;
  }
  return survey.Check(error);
}

Eigen::Matrix3d WorldFromCamRotation(double yaw, double pitch, double roll) {
  const Eigen::Vector3d forward(std::cos(yaw), std::sin(yaw), 0.0);
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d level;
  level << right, down, forward;
  // Pitch turns about the camera x axis (positive = looking up), roll about its z axis.
  return level * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix() *
         Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

Trajectory::Trajectory(const Scene& scene, const TrajectoryOptions& options)
    : options_(options),
      scene_(scene),
      look_cache_(std::make_shared<LookCache>()),
      yaw_cache_(std::make_shared<YawCache>()) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const std::vector<Eigen::Vector2d>& tour = scene.tour;
  const size_t n = tour.size();
  SIGHTMAP_CHECK(n >= 3, "the scene's tour needs at least 3 points");
  if (options.kind == TrajectoryKind::kSurvey) {
    survey_plan_ = PlanSurvey(scene, options.survey);
    polyline_ = survey_plan_->path;
  } else {
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d& p0 = tour[(i + n - 1) % n];
      const Eigen::Vector2d& p1 = tour[i];
      const Eigen::Vector2d& p2 = tour[(i + 1) % n];
      const Eigen::Vector2d& p3 = tour[(i + 2) % n];
      const int steps = std::max(2, static_cast<int>((p2 - p1).norm() / 0.02));
      for (int j = 0; j < steps; ++j) {
        polyline_.push_back(CatmullRom(p0, p1, p2, p3, static_cast<double>(j) / steps));
      }
    }
    polyline_.push_back(polyline_.front());
  }
  arc_.assign(polyline_.size(), 0.0);
  for (size_t i = 1; i < polyline_.size(); ++i) {
    arc_[i] = arc_[i - 1] + (polyline_[i] - polyline_[i - 1]).norm();
  }
  lap_length_m_ = arc_.back();
  const double turn_rate_dps = options.max_turn_rate_dps > 0.0
                                   ? options.max_turn_rate_dps
                                   : (options.kind == TrajectoryKind::kRobot ? 30.0 : 35.0);
  turn_rate_rad_s_ = DegToRad(turn_rate_dps);
  speed_mps_ = options.speed_mps > 0.0                     ? options.speed_mps
               : options.kind == TrajectoryKind::kHandheld ? 0.5
               : options.kind == TrajectoryKind::kRobot    ? 0.4
                                                           : 0.3;
  // Session N starts at tour point 7 * (N - 1): another door, another room.
  const size_t start_point = (7 * static_cast<size_t>(options.session - 1)) % n;
  double start = 0.0;
  for (size_t i = 0; i < start_point; ++i) start += (tour[(i + 1) % n] - tour[i]).norm();
  start_s_m_ = lap_length_m_ * start / [&] {
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) total += (tour[(i + 1) % n] - tour[i]).norm();
    return total;
  }();
  std::mt19937_64 rng(MixSeed(options.seed, 0x7a11'0000ULL + options.session));
  for (double& phase : phases_) phase = UniformReal(rng, 0.0, 2 * kPi);
  if (survey_plan_) {
    BuildSurveyLegs();
    // Session N starts a golden-ratio share of the lap further on: another room each time.
    const double share = std::fmod(0.6180339887 * (options.session - 1), 1.0);
    survey_start_s_ = share * survey_lap_s_;
  }
  for (const Appliance& appliance : scene.appliances) {
    // Ceiling fixtures are mapped in passing, not stared at.
    for (const Eigen::Vector3d& p : appliance.points) {
      if (p.z() < 2.2) look_targets_.push_back(p);
    }
  }
}

Eigen::Vector2d Trajectory::PositionAt(double s_m) const {
  double s = std::fmod(s_m, lap_length_m_);
  if (s < 0) s += lap_length_m_;
  const auto it = std::upper_bound(arc_.begin(), arc_.end(), s);
  const size_t i = std::clamp<size_t>(static_cast<size_t>(it - arc_.begin()), 1, arc_.size() - 1);
  const double seg = arc_[i] - arc_[i - 1];
  const double a = seg > 0 ? (s - arc_[i - 1]) / seg : 0.0;
  return (1 - a) * polyline_[i - 1] + a * polyline_[i];
}

double Trajectory::lap_duration_s() const {
  return survey_plan_ ? survey_lap_s_ : lap_length_m_ / speed_mps_;
}

namespace {
constexpr double kSurveyAccel = 0.5;  // walking speeds up and slows down at this [m/s^2]

// Distance covered t seconds into a leg of `length` walked from standstill to standstill at up to
// `speed` (a trapezoidal speed profile; triangular when the leg is short).
double LegDistance(double length, double speed, double t) {
  if (length <= 0.0) return 0.0;
  const double a = kSurveyAccel;
  const double cruise_speed = std::min(speed, std::sqrt(a * length));
  const double ramp_s = cruise_speed / a;
  const double ramp_m = 0.5 * a * ramp_s * ramp_s;
  const double cruise_s = (length - 2 * ramp_m) / cruise_speed;
  if (t <= 0.0) return 0.0;
  if (t < ramp_s) return 0.5 * a * t * t;
  if (t < ramp_s + cruise_s) return ramp_m + cruise_speed * (t - ramp_s);
  const double u = std::min(t - ramp_s - cruise_s, ramp_s);
  return ramp_m + cruise_speed * cruise_s + cruise_speed * u - 0.5 * a * u * u;
}

double LegDuration(double length, double speed) {
  if (length <= 0.0) return 0.0;
  const double cruise_speed = std::min(speed, std::sqrt(kSurveyAccel * length));
  return length / cruise_speed + cruise_speed / kSurveyAccel;
}
}  // namespace

void Trajectory::BuildSurveyLegs() {
  const std::vector<SurveyStop>& stops = survey_plan_->stops;
  double t = 0.0;
  for (size_t i = 0; i < stops.size(); ++i) {
    if (stops[i].target && options_.dwell_s > 0.0) {
      survey_legs_.push_back({t, options_.dwell_s, 0.0, stops[i].arc_m, 0.0, stops[i].target, {}});
      t += options_.dwell_s;
    }
    const double end = i + 1 < stops.size() ? stops[i + 1].arc_m : lap_length_m_;
    const double length = std::max(end - stops[i].arc_m, 0.0);
    // At least 2 s between two standpoints, however close: the operator turns from one
    // appliance to the next.
    const double walk_s = LegDuration(length, speed_mps_);
    const double duration = std::max(walk_s, 2.0);
    survey_legs_.push_back({t, duration, walk_s / duration, stops[i].arc_m, length, stops[i].target,
                            stops[(i + 1) % stops.size()].target});
    t += duration;
  }
  SIGHTMAP_CHECK(!survey_legs_.empty() && t > 0.0, "the survey plan has no legs");
  survey_lap_s_ = t;
}

const Trajectory::SurveyLeg& Trajectory::SurveyLegAt(double t_s, double* t_in_leg_s) const {
  double t = std::fmod(survey_start_s_ + std::max(t_s, 0.0), survey_lap_s_);
  const auto it =
      std::upper_bound(survey_legs_.begin(), survey_legs_.end(), t,
                       [](double value, const SurveyLeg& leg) { return value < leg.t0_s; });
  const SurveyLeg& leg = it == survey_legs_.begin() ? survey_legs_.front() : *std::prev(it);
  *t_in_leg_s = std::clamp(t - leg.t0_s, 0.0, leg.duration_s);
  return leg;
}

double Trajectory::SurveyDistance(const SurveyLeg& leg, double t_in_leg_s) const {
  return leg.s0_m + LegDistance(leg.length_m, speed_mps_, t_in_leg_s * leg.pace);
}

Trajectory::Gait Trajectory::GaitAt(double t_s, const Eigen::Vector2d& position, double path_yaw,
                                    double stepping) const {
  const double* ph = phases_;
  const double step_hz = 1.8;
  Gait gait;
  gait.height = 1.55 + 0.08 * std::sin(2 * kPi * t_s / 40.0 + ph[1]) +
                0.025 * stepping * std::sin(2 * kPi * step_hz * t_s + ph[2]);
  const Eigen::Vector2d left(-std::sin(path_yaw), std::cos(path_yaw));
  gait.swayed = position + 0.02 * stepping * std::sin(kPi * step_hz * t_s + ph[3]) * left;
  gait.roll = 0.06 * std::sin(2 * kPi * t_s / 7.0 + ph[7]) +
              0.02 * stepping * std::sin(2 * kPi * step_hz * t_s + ph[2]);
  return gait;
}

double Trajectory::DistanceAt(double t_s) const {
  if (survey_plan_) {
    double t_in_leg = 0.0;
    const SurveyLeg& leg = SurveyLegAt(t_s, &t_in_leg);
    return SurveyDistance(leg, t_in_leg);
  }
  double s = start_s_m_ + speed_mps_ * t_s;
  if (options_.kind == TrajectoryKind::kHandheld) {
    // +-10% pace change over ~25 s (integral of the speed modulation).
    const double omega = 2 * kPi / 25.0;
    s += 0.1 * speed_mps_ / omega * (std::sin(omega * t_s + phases_[0]) - std::sin(phases_[0]));
  }
  return s;
}

namespace {
constexpr double kWindowS = 10.0;  // look-target window [s]

// 0 at the window's edges, 1 over its middle: turns ease in and out.
double WindowWeight(double t_s) {
  const double phase = t_s / kWindowS - std::floor(t_s / kWindowS);
  return SmoothStep((phase - 0.02) / 0.25) * (1.0 - SmoothStep((phase - 0.73) / 0.25));
}
}  // namespace

std::optional<Eigen::Vector3d> Trajectory::LookTarget(double t_s, double eye_height_m) const {
  const int64_t window = static_cast<int64_t>(std::floor(t_s / kWindowS));
  const auto key = std::make_pair(window, static_cast<int>(std::lround(eye_height_m * 100)));
  {
    const std::lock_guard<std::mutex> lock(look_cache_->mutex);
    const auto it = look_cache_->targets.find(key);
    if (it != look_cache_->targets.end()) return it->second;
  }
  const std::optional<Eigen::Vector3d> target = ChooseLookTarget(window, eye_height_m);
  const std::lock_guard<std::mutex> lock(look_cache_->mutex);
  look_cache_->targets[key] = target;
  return target;
}

std::optional<Eigen::Vector3d> Trajectory::ChooseLookTarget(int64_t window_index,
                                                            double eye_height_m) const {
  const double middle = (static_cast<double>(window_index) + 0.5) * kWindowS;
  const double s = DistanceAt(middle);
  const Eigen::Vector2d anchor = PositionAt(s);
  const Eigen::Vector2d ahead = PositionAt(s + 0.8) - PositionAt(s - 0.8);
  const double heading = std::atan2(ahead.y(), ahead.x());
  const bool appliance_window = window_index % 2 == 0;
  if (appliance_window) {
    double best = 4.0;
    std::optional<Eigen::Vector3d> target;
    for (const Eigen::Vector3d& p : look_targets_) {
      const double d = (p.head<2>() - anchor).norm();
      const Room* room = scene_.RoomAt(p.head<2>());
      if (d < best && d > 1.0 && room != nullptr && room == scene_.RoomAt(anchor)) {
        best = d;
        target = p;
      }
    }
    if (target) return target;
  }
  // In a horizontal direction within 110 deg of the heading, the view the sensor maps best (most
  // of it within range, things rather than bare walls: people and mapping robots look at things),
  // its centre 1.6-3.8 m away and preferably about 3 m.
  const Eigen::Vector3d eye(anchor.x(), anchor.y(), eye_height_m);
  double best_score = -1e9;
  std::optional<Eigen::Vector3d> target;
  for (int i = -11; i <= 11; ++i) {
    const double yaw = heading + DegToRad(i * (110.0 / 11.0));
    const Eigen::Vector3d dir(std::cos(yaw), std::sin(yaw), 0.0);
    const auto hit = scene_.Raycast(eye, dir, 3.8);
    if (!hit || hit->first < 1.6) continue;
    const double score =
        ViewScore(scene_, eye, yaw) - std::abs(hit->first - 3.0) - 0.2 * std::abs(i) / 11.0;
    if (score > best_score) {
      best_score = score;
      target = eye + hit->first * dir;
    }
  }
  return target;
}

Eigen::Isometry3d Trajectory::WorldFromCam(double t_s) const {
  const Attitude desired = DesiredAt(t_s);
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear() = WorldFromCamRotation(LimitedYaw(t_s), desired.pitch, desired.roll);
  world_from_cam.translation() = desired.position;
  return world_from_cam;
}

double Trajectory::LimitedYaw(double t_s) const {
  // The heading follows the desired one at no more than max_turn_rate: sampled on a fixed grid
  // from t = 0 (so any frame's pose is the same whichever frames were asked for before) and
  // interpolated. Samples are unwrapped angles, so interpolation never crosses +-pi the long way.
  constexpr double kStepS = 1.0 / 60.0;
  const double max_step = turn_rate_rad_s_ * kStepS;
  const double u = std::max(t_s, 0.0) / kStepS;
  const size_t k = static_cast<size_t>(std::floor(u));
  const std::lock_guard<std::mutex> lock(yaw_cache_->mutex);
  std::vector<double>& samples = yaw_cache_->samples;
  while (samples.size() <= k + 1) {
    const double t = static_cast<double>(samples.size()) * kStepS;
    const double desired = DesiredAt(t).yaw;
    if (samples.empty()) {
      samples.push_back(desired);
    } else {
      const double previous = samples.back();
      samples.push_back(previous + std::clamp(WrapAngle(desired - previous), -max_step, max_step));
    }
  }
  const double a = u - static_cast<double>(k);
  return (1.0 - a) * samples[k] + a * samples[k + 1];
}

Trajectory::Attitude Trajectory::DesiredAt(double t_s) const {
  if (survey_plan_) return SurveyDesiredAt(t_s);
  const double s = DistanceAt(t_s);
  const Eigen::Vector2d position = PositionAt(s);
  // Heading along the path, looking ahead and behind to smooth the spline's corners.
  const Eigen::Vector2d ahead = PositionAt(s + 0.8) - PositionAt(s - 0.8);
  const double path_yaw = std::atan2(ahead.y(), ahead.x());
  const double w = WindowWeight(t_s);
  if (options_.kind == TrajectoryKind::kRobot) {
    // The pan-tilt head keeps the camera on one target per window and pans to the next one over
    // the window's last quarter, rather than facing down the path between targets: at 0.75 m a
    // Kinect looking down a corridor or a 10 m room sees mostly beyond its 4.5 m range.
    auto yaw_towards = [&](const std::optional<Eigen::Vector3d>& target) {
      if (!target) return path_yaw;
      const Eigen::Vector2d to = target->head<2>() - position;
      return to.norm() < 0.3 ? path_yaw : std::atan2(to.y(), to.x());
    };
    const double phase = t_s / kWindowS - std::floor(t_s / kWindowS);
    const double pan = SmoothStep((phase - 0.75) / 0.25);
    const double yaw_now = yaw_towards(LookTarget(t_s, 0.75));
    const double yaw_next = yaw_towards(LookTarget(t_s + kWindowS, 0.75));
    const double yaw = yaw_now + pan * WrapAngle(yaw_next - yaw_now);
    return {Eigen::Vector3d(position.x(), position.y(), 0.75), yaw, 0.0, 0.0};
  }
  const double* ph = phases_;
  const Gait gait = GaitAt(t_s, position, path_yaw, 1.0);
  double height = gait.height;
  const Eigen::Vector2d& swayed = gait.swayed;
  // A small sweep over the walls: two incommensurate periods so the pattern does not repeat.
  double yaw = path_yaw + 0.25 * std::sin(2 * kPi * t_s / 13.0 + ph[4]) +
               0.12 * std::sin(2 * kPi * t_s / 5.3 + ph[5]);
  double pitch = -0.12 + 0.1 * std::sin(2 * kPi * t_s / 9.0 + ph[6]);
  const double roll = gait.roll;
  // Targets are chosen once per window at the walk's mean eye height.
  if (const auto target = LookTarget(t_s, 1.55)) {
    const Eigen::Vector2d to = target->head<2>() - swayed;
    const double target_yaw = std::atan2(to.y(), to.x());
    const double target_pitch = std::atan2(target->z() - height, std::max(to.norm(), 0.3));
    yaw += w * WrapAngle(target_yaw - yaw);
    pitch += w * (target_pitch - 0.1 - pitch);  // aim a little low: people look down at things
  }
  pitch = std::clamp(pitch, -0.26, 0.26);  // +-15 deg
  height = std::clamp(height, 1.4, 1.7);
  return {Eigen::Vector3d(swayed.x(), swayed.y(), height), yaw, pitch, roll};
}

Trajectory::Attitude Trajectory::SurveyDesiredAt(double t_s) const {
  double t_in_leg = 0.0;
  const SurveyLeg& leg = SurveyLegAt(t_s, &t_in_leg);
  const double s = SurveyDistance(leg, t_in_leg);
  const Eigen::Vector2d position = PositionAt(s);
  const Eigen::Vector2d ahead = PositionAt(s + 0.8) - PositionAt(s - 0.8);
  const double path_yaw = std::atan2(ahead.y(), ahead.x());
  const bool walking = leg.pace > 0.0;
  const double* ph = phases_;
  // Steps only while walking: standing, the sensor drifts with the operator's breathing and hands.
  const double stepping =
      walking ? std::min(1.0, std::min(t_in_leg, leg.duration_s - t_in_leg) / 1.0) : 0.0;
  const Gait gait = GaitAt(t_s, position, path_yaw, stepping);
  const Eigen::Vector2d& swayed = gait.swayed;
  // Looking ahead with a small sweep over the walls while walking, at the appliance standing.
  double yaw = path_yaw + 0.2 * std::sin(2 * kPi * t_s / 13.0 + ph[4]) +
               0.1 * std::sin(2 * kPi * t_s / 5.3 + ph[5]);
  double pitch = -0.12 + 0.08 * std::sin(2 * kPi * t_s / 9.0 + ph[6]);
  const double roll = gait.roll;
  const double height = std::clamp(gait.height, 1.4, 1.7);
  const Eigen::Vector3d eye(swayed.x(), swayed.y(), height);
  if (walking) yaw = OpenYaw(eye, yaw);
  // Turned (by weight w) to the appliance stood at, or while walking from the previous one over
  // the leg's first 1.5 s and to the next one over its last 2 s; one after the other, so the
  // attitude stays continuous however short the leg (the heading itself then turns no faster
  // than max_turn_rate).
  const double tremor = 0.01 * std::sin(2 * kPi * t_s / 3.1 + ph[4]);  // standing frames differ
  auto turn_to = [&](const std::optional<Eigen::Vector3d>& target, double w) {
    if (!target || w <= 0.0) return;
    const Eigen::Vector2d to = target->head<2>() - swayed;
    const double target_yaw = std::atan2(to.y(), to.x());
    const double target_pitch = std::atan2(target->z() - height, std::max(to.norm(), 0.3));
    yaw += w * (WrapAngle(target_yaw - yaw) + tremor);
    pitch += w * (target_pitch - pitch + tremor);
  };
  if (!walking) {
    turn_to(leg.target, 1.0);
  } else {
    // Over the whole leg when it is shorter than that.
    const double away_s = std::min(1.5, leg.duration_s);
    const double towards_s = std::min(2.0, leg.duration_s);
    turn_to(leg.target, 1.0 - SmoothStep(t_in_leg / away_s));
    turn_to(leg.next_target, SmoothStep((t_in_leg - (leg.duration_s - towards_s)) / towards_s));
  }
  pitch = std::clamp(pitch, -0.61, 0.61);  // +-35 deg: up at ceiling lights, down at a printer
  return {eye, yaw, pitch, roll};
}

double Trajectory::OpenYaw(const Eigen::Vector3d& eye, double yaw) const {
  // Open: nothing within 1.2 m straight ahead nor within 0.8 m 20 deg to either side.
  auto open = [&](double a) {
    for (const auto& [offset, reach] : {std::pair{0.0, 1.2}, {-0.35, 0.8}, {0.35, 0.8}}) {
      const Eigen::Vector3d dir(std::cos(a + offset), std::sin(a + offset), 0.0);
      if (scene_.Raycast(eye, dir, reach)) return false;
    }
    return true;
  };
  if (open(yaw)) return yaw;
  for (int step = 1; step <= 12; ++step) {
    for (const double sign : {1.0, -1.0}) {
      const double turned = yaw + DegToRad(sign * step * 10.0);
      if (open(turned)) return turned;
    }
  }
  return yaw;
}

}  // namespace sightmap::sim
