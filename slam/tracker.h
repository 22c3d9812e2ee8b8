// Tracking at the sensor's rate: every frame the source delivers is placed relative to the newest
// keyframe, and the tracker decides which frames become keyframes.
//
// The paper keeps one keyframe a second, but its RTAB-Map tracked the frames in between; frames
// 33-100 ms apart almost always overlap where frames a second apart often do not. Per frame:
//  1. Features, registered to the reference (the newest keyframe) with the constant-velocity
//     prediction as the guided-matching prior.
//  2. When that fails and the last frame was registered by features, that frame becomes a
//     keyframe (it still overlapped the reference) and this one is registered to it instead:
//     keyframes are inserted where the overlap runs out, not only on the 1 Hz clock.
//  3. When features fail too (a bare wall, a door frame), dense RGB-D odometry between this frame
//     and the previous one (OpenCV's RgbdICPOdometry: point-to-plane ICP and photometric error),
//     started from the prediction and refused when it strays far from it. Along the directions
//     the geometry leaves free (the slide along a bare wall) it keeps the registered frames'
//     velocity instead. Frames a second or more apart (a 1 Hz folder) may be searched instead
//     (dense_search, off by default): dense alignment from the prediction turned by a range of
//     yaw offsets, strictly checked, as a walker or a robot's head turns up to 35 degrees
//     between them.
//  4. When nothing registers (the view is blind for a moment), the frame is placed by the motion
//     model; after blind_keyframe_after_s a frame with enough 3D points becomes a keyframe linked
//     to the last one by that prediction, with a covariance that grows with the blind time. The
//     map stays one graph and a later loop closure corrects the guess.
//
// A keyframe is emitted with its motion from the previously emitted keyframe, so the mapper needs
// no registration of its own to continue the chain. One thread calls Track; no threads inside.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "capture/keyframe_sampler.h"
#include "core/camera.h"
#include "core/rgbd_frame.h"
#include "slam/dense_alignment.h"
#include "slam/dense_rescue.h"
#include "slam/features.h"
#include "slam/registration.h"

namespace sightmap::slam {

struct TrackerOptions {
  FeatureOptions features;
  RegistrationOptions registration;
  // Keyframes per second of source time, on the whole periods of its clock [Hz]; 0 makes
  // every placed frame a keyframe.
  double keyframe_rate_hz = 1.0;
  // A frame registered to the reference with fewer inliers than this share of the most any frame
  // had against it is losing the overlap: it becomes a keyframe early so that the next frames
  // register to it. Relative, because a bare room never has many inliers: there a keyframe comes
  // only when registration fails (the last placed frame is taken then). The same share applies to
  // the inliers within registration.near_depth_m: far points alone cannot tell a sideways step
  // from a turn (the robot's head panning from a room's far wall onto a desk kept 156 inliers,
  // all 5-8 m away, and that keyframe's link erred 8 cm).
  double min_reference_inlier_ratio = 0.35;
  // A frame with this many times the reference's 3D keypoints becomes a keyframe early: a view
  // turning away from a bare wall is a better reference than the wall (registration to the wall's
  // few keypoints is the least accurate).
  double richer_reference_ratio = 2.0;
  // No early keyframe closer than this to the previous one [s].
  double min_keyframe_interval_s = 0.15;
  // Depth kept per frame for registration's dense check, 1/N of the image (as the mapper's).
  int depth_downscale = 4;

  // A registration further than this from the constant-velocity prediction is refused: it matched
  // a repeated texture (a second of walk holds no such jump). Rates times the time since the last
  // frame the registration placed, plus the slack; tighter bounds (0.5 m/s, 20 deg/s) refused
  // right registrations of a walker's sweeps and tripled the blind frames [m/s], [deg/s], [m],
  // [deg].
  double max_deviation_mps = 1.0;
  double max_deviation_dps = 60.0;
  double deviation_slack_m = 0.05;
  double deviation_slack_deg = 3.0;

  // Dense fallback on consecutive frames (dense_alignment.h).
  bool dense_fallback = true;
  // Dense alignment converges only from a prediction within a few degrees: frames further apart
  // than this (a 1 Hz folder, where a walker turns 35 degrees between frames) are placed by the
  // motion model instead. On the 1 Hz seed 11 walk, 8 of its 10 dense steps were 17-70 degrees
  // or 0.7 m off while claiming 4 cm and 1 degree [s].
  double dense_max_interval_s = 0.35;
  // A dense step starts from the motion model's prediction, further off than a registration when a
  // turn begins, so the tracker keeps OpenCV's four pyramid levels. With two, the robot walk (seed
  // 11, 10 Hz) drifted 0.8 m over t = 565-568 s (ATE 0.21 m against 0.045 m). Unlike the
  // mapper's refinement it counts pale texture on every level: there the robot walk's frames
  // before a pale print at t = 180-190 s erred 0.063 m at worst, 0.157 m with 10 on the coarse
  // levels (ATE 0.0217 m against 0.0229).
  DenseAlignmentOptions dense = [] {
    DenseAlignmentOptions options;
    options.iterations_per_level = {7, 7, 7, 10};
    options.min_gradient_per_level = {3.0, 3.0, 3.0, 3.0};
    return options;
  }();
  // A dense step is refused when it differs from the constant-velocity prediction by more than
  // these rates times the frame interval (plus the slack): ICP on a bare wall slides along it
  // [m/s], [deg/s], [m], [deg].
  double dense_max_deviation_mps = 0.3;
  double dense_max_deviation_dps = 30.0;
  double dense_slack_m = 0.02;
  double dense_slack_deg = 1.0;
  // Nor may a dense step move faster than a walker or a robot does (plus the slack): the
  // constant-velocity bound follows the velocity the chain itself sets, so a chain sliding along a
  // bare wall can speed up a little each frame (seed 11, 10 Hz: 1.18 m in 7 frames, claiming
  // 9 cm) [m/s], [deg/s].
  double dense_max_speed_mps = 1.0;
  double dense_max_turn_rate_dps = 90.0;
  // Standard deviation of one dense step, accumulated along a chain [m], [rad].
  // ICP slides along bare walls: measured on the simulated walk, steps err by 0.2-3 cm.
  double dense_step_sigma_m = 0.02;
  double dense_step_sigma_rad = 0.01;
  // A dense step keeps the velocity of the recent registered frames (SmoothedVelocity) in the
  // directions its geometry leaves nearly free (KeepPriorWhereWeak with this ratio and lever).
  // Before a single wall each dense step started from the last one's velocity, and ICP kept what
  // it was given and added its own slide along the wall: on the robot walk (seed 11, 10 Hz) a
  // 16-frame chain sped up to three times the robot's speed and left a keyframe 0.52 m off (ATE
  // 0.0396 -> 0.0344 m with this, hand-held 0.0194 -> 0.0190 m). A ratio of 0.03 also took the
  // prior where the walker's texture fixed ICP (hand-held 0.0212 m); 0 turns this off [-], [m].
  double dense_weak_eigen_ratio = 0.01;
  double dense_weak_lever_m = 1.5;
  // A dense step that fits the frame to the last one worse than no motion at all, by every figure
  // of DenseAligner::Fit, is replaced by no motion: the walker stood still where the alignment
  // slid (a bare projection screen filling the view on the survey walk, seed 11, t = 425-430 s).
  bool dense_prefer_rest = true;

  // Frames further apart than dense_max_interval_s (a 1 Hz folder): a registration the dense check
  // refused, or accepted seeing through more than the rescue's strict share, is aligned densely
  // from its pose and checked again (dense_rescue.h). On the 1 Hz hand-held walks (seeds 1, 3, 5,
  // 7, 11, 23) 0.252 / 0.099 / 0.127 / 0.254 / 0.188 / 0.176 m -> 0.329 / 0.082 / 0.130 / 0.114 /
  // 0.065 / 0.085 m. Not at the sensor's rate, where the dense fallback follows the frames: there
  // it took the 10 Hz hand-held walk (seed 11) from 0.0112 to 0.0161 m, the robot's from 0.0137
  // to 0.0150 m.
  DenseRescueOptions dense_rescue;
  // Frames further apart than dense_max_interval_s that features did not register: dense
  // alignment from the motion model turned by the search's yaw offsets, checked as the rescue
  // checks (dense_rescue.h; off by default, measured there). Its step is trusted in rotation to
  // dense_search_sigma_rad and in translation to the motion model's sigma for the interval, since
  // a slide along a pale wall stays free [rad].
  DenseSearchOptions dense_search;
  double dense_search_sigma_rad = 0.02;

  // Where a frame does not register but the last one did, the dense step starts from, and a blind
  // frame is placed by, the smoothed velocity of the recent registered frames (SmoothedVelocity)
  // rather than the last frame's step: a registration that matched a repeated texture leaves a
  // step centimetres off, and the next frame, predicted from it, was refused by the dense step's
  // deviation bound, fell blind and made a prior link nothing corrects (the robot walk, seed 11,
  // 10 Hz, driving at a window above a radiator at t = 330-336 s: three prior links 60-70 mm off).
  // Only at the sensor's rate (frames at most dense_max_interval_s apart): over a 1 Hz walk's
  // seconds the smoothed velocity lags a walker's turns (seed 1: ATE 0.62 -> 7.0 m).
  bool fallback_on_smoothed_velocity = true;

  // Blind frames: the motion model's standard deviation is sigma + rate x blind time [m], [m/s],
  // [rad], [rad/s] (a walker keeps pace for a second but turns unpredictably).
  double prior_sigma_m = 0.02;
  double prior_sigma_mps = 0.3;
  double prior_sigma_rad = 0.02;
  double prior_sigma_radps = 0.6;
  // While frames are blind the predicted velocity fades by this factor a frame: the last
  // registered step may be the bad one that preceded the blindness.
  double blind_velocity_decay = 0.8;
  // After this long without any registration a frame becomes a keyframe on the prediction [s].
  double blind_keyframe_after_s = 0.3;
  // Frames with fewer 3D keypoints make poor references: a blind stretch waits for a better one.
  int min_reference_points = 30;
  // When positive, the map's first keyframe is a frame with min_reference_points that the next
  // frame registers to; when start_max_wait_s passes without one, the last rich frame (or the
  // richest frame when none was rich). A walk that starts facing a bare wall, or turning fast,
  // otherwise anchors the map on a keyframe nothing registers to, joined to the rest only by the
  // motion model: the simulator's seed 1 walk (16 3D keypoints, a 0.3 s blind link claiming no
  // motion while the walker turned 10 degrees) and seed 23 walk (30 keypoints, frames 1-3 blind)
  // gave maps 10.4 and 10.6 degrees off their anchor. 0 starts on the first frame [s].
  double start_max_wait_s = 1.0;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const TrackerOptions& options);
void from_json(const nlohmann::json& json, TrackerOptions& options);

// The camera's velocity from the frames that registered, smoothed over the last few: each
// registration errs by its own few millimetres, so one frame's step from the last is a poor
// velocity (its prediction of the next registered frame erred by a median 1.0 cm on the robot
// walk, whose true constant-velocity prediction errs by 0.1 cm).
class SmoothedVelocity {
 public:
  // A registered frame's step from the last frame (last_from_cam) over dt_s [s].
  void Add(const Eigen::Isometry3d& step, double dt_s);
  bool empty() const { return !has_velocity_; }
  // The velocity's step over dt_s (identity while empty).
  Eigen::Isometry3d Step(double dt_s) const;

 private:
  Eigen::Matrix<double, 6, 1> velocity_ = Eigen::Matrix<double, 6, 1>::Zero();  // [m/s], [rad/s]
  bool has_velocity_ = false;
};

// How a keyframe's pose relative to the previous keyframe was found.
enum class MotionSource {
  kRegistered,  // features registered directly to the previous keyframe
  kChained,     // through frames in between registered densely
  kPrior,       // the motion model across frames where nothing registered
};
const char* ToString(MotionSource source);

struct KeyframeMotion {
  MotionSource source = MotionSource::kRegistered;
  // The keyframe's camera in the previous keyframe's camera frame.
  Eigen::Isometry3d previous_from_cam = Eigen::Isometry3d::Identity();
  // Inverse covariance, translation then rotation (registration's convention).
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
  int inliers = 0;       // of the direct registration (0 for a prior)
  double blind_s = 0.0;  // time covered by the motion model alone [s]
};

struct TrackedKeyframe {
  RgbdFrame frame;  // images, timestamp, index and ground truth as the source gave them
  Features features;
  cv::Mat depth_small;                   // depth_downscale x smaller, nearest samples
  std::optional<KeyframeMotion> motion;  // none for the tracker's first keyframe
};

enum class FrameTracking { kRegistered, kDense, kBlind };
const char* ToString(FrameTracking tracking);

// What one frame did.
struct TrackResult {
  FrameTracking tracking = FrameTracking::kRegistered;
  // Keyframes decided by this frame, oldest first (0, 1 or 2: the previous frame when the overlap
  // was lost, then maybe this one).
  std::vector<TrackedKeyframe> keyframes;
  int inliers = 0;  // to the reference, when registered
  // Where the frame is: in the camera frame of the newest keyframe (the source's frame index).
  int64_t reference_index = 0;
  Eigen::Isometry3d reference_from_cam = Eigen::Isometry3d::Identity();
  double features_s = 0.0;
  double registration_s = 0.0;
  double dense_s = 0.0;
  double total_s = 0.0;
};

struct TrackerCounters {
  int64_t frames = 0;
  int64_t registered = 0;     // by features to a keyframe
  int64_t dense = 0;          // by the dense fallback
  int64_t dense_at_rest = 0;  // of those, placed unmoved (TrackerOptions::dense_prefer_rest)
  int64_t blind = 0;          // by the motion model only
  int64_t searched = 0;       // of `dense`, a second or more apart, found by the dense search
  int64_t rescued = 0;  // of `registered`, refused by the dense check and placed by dense alignment
  int64_t keyframes = 0;
  int64_t early_keyframes = 0;  // off the rate's clock: overlap lost or weak
  int64_t prior_keyframes = 0;  // emitted on the motion model
  int64_t before_start = 0;     // frames seen before the first keyframe and never placed
};

class Tracker {
 public:
  Tracker(const Intrinsics& camera, const TrackerOptions& options = TrackerOptions());
  ~Tracker();
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  // Places one frame (colour BGR 8-bit and depth 16-bit mm of the camera's size). Throws
  // InvalidArgument for images that do not fit the camera.
  TrackResult Track(const RgbdFrame& frame);

  // Continues a walk whose newest keyframe is `keyframe` (a replay resumed after its last stored
  // frame): it becomes the reference as if this tracker had emitted it, so the next frames are
  // placed relative to it and the next keyframe carries its motion from it, instead of starting a
  // walk of its own by features alone. The velocity starts at rest. Only before the first frame;
  // throws InvalidArgument for images that do not fit the camera.
  void ContinueFrom(const RgbdFrame& keyframe);

  // The end of the stream: when it ended before the first keyframe (every frame was a poor
  // reference, within start_max_wait_s), the richest of them becomes the first keyframe.
  TrackResult Finish();

  const TrackerCounters& counters() const { return counters_; }

 private:
  struct Placed;  // a frame with its features and its pose relative to the reference

  Placed Prepare(const RgbdFrame& frame, TrackResult* result) const;
  // Whether a registration succeeded with a finite pose and information, within the walker's
  // reach (max_deviation_*) of `predicted` after `since_placed_s`.
  bool Believable(const RegistrationResult& registration, const Eigen::Isometry3d& predicted,
                  double since_placed_s) const;
  // Registers `frame` to the reference by features; true when it succeeded.
  bool RegisterToReference(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                           TrackResult* result);
  bool RegisterDensely(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                       TrackResult* result);
  // A frame further than dense_max_interval_s from the last: dense_search from `predicted`.
  bool SearchDensely(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                     TrackResult* result);
  DenseImage DenseImageOf(const RgbdFrame& frame) const;
  // `placed` prepared for dense alignment, once.
  DenseAligner::Frame& DenseOf(Placed& placed) const;
  // Whether `current` fits `last` at least as well unmoved as at `last_from_current` by every
  // DenseFit figure (pairs, depth and grey residuals).
  bool StandingStillFitsBetter(DenseAligner::Frame& current, DenseAligner::Frame& last,
                               const Eigen::Isometry3d& last_from_current) const;
  void PlaceBlind(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s) const;
  // Places `frame` relative to the reference: features, then the last frame as a new keyframe,
  // then dense odometry, then the motion model. Updates the velocity and the counters.
  FrameTracking Place(Placed& frame, double dt_s, TrackResult* result);
  // Whether `frame`, placed by `tracking`, should become a keyframe off the rate's clock.
  bool WantsEarlyKeyframe(const Placed& frame, FrameTracking tracking) const;
  // Emits `frame` as a keyframe and makes it the reference.
  void Emit(Placed& frame, bool early, TrackResult* result);
  // Before the first keyframe: emits the candidate (a frame with min_reference_points) as it once
  // `frame` registers to it, else keeps `frame` as the candidate when it is rich (or the richest);
  // once the wait is over, emits the candidate (or `frame` when it is richer than a poor
  // candidate). True when an earlier frame was emitted, so `frame` is still to be placed.
  bool StartOnEarlierFrame(Placed& frame, TrackResult* result);
  // Whether `frame` registers to `reference` by features, without a prediction.
  bool RegistersTo(const Placed& frame, const Placed& reference) const;
  // Emits `first` as the map's first keyframe and makes it the last frame placed.
  void StartMapOn(Placed& first, TrackResult* result);

  Intrinsics camera_;
  TrackerOptions options_;
  std::unique_ptr<Placed> reference_;    // the newest keyframe
  std::unique_ptr<Placed> last_;         // the newest frame placed (may be the reference)
  int reference_best_inliers_ = 0;       // the most inliers a frame had against the reference
  int reference_best_near_inliers_ = 0;  // and the most of them within near_depth_m
  Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();  // last step: previous_from_last
  double velocity_dt_s_ = 0.0;
  SmoothedVelocity registered_velocity_;
  capture::KeyframeSampler rate_;  // the keyframe rate's clock; early keyframes do not move it
  TrackerCounters counters_;
  DenseAligner aligner_;
  std::unique_ptr<Placed> start_candidate_;  // before the first keyframe: the richest frame yet
  TimestampNs first_timestamp_ns_ = 0;       // of the first frame seen
};

// The world poses of the frames a Tracker places, chained from the keyframe motions it emits: what
// the tracker alone says, before a mapper optimises anything (for measuring its drift against
// ground truth). The first keyframe stands at its frame's ground truth when it has one, else at
// the origin.
class TrackedChain {
 public:
  // Takes `result`'s keyframes and returns the frame's world_from_cam; nothing before the first
  // keyframe.
  std::optional<Eigen::Isometry3d> Add(const TrackResult& result);

 private:
  std::optional<Eigen::Isometry3d> world_from_newest_;  // the newest keyframe's pose
  int64_t newest_index_ = -1;
};

}  // namespace sightmap::slam
