#include "slam/tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "slam/pose_graph.h"

namespace sightmap::slam {
namespace {

using Clock = std::chrono::steady_clock;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// Registration's information can be singular along a degenerate direction: a tiny ridge keeps the
// inverse finite, and the mapper's floor decides how much such a link is trusted.
Matrix6 Inverse(const Matrix6& m) { return RidgedInverse(m, 1e-12); }

// SmoothedVelocity weighs the newest registered frame by this: about the last five count.
constexpr double kVelocityWeight = 0.2;

// The motion `step` repeated `scale` times (its rotation angle and translation scaled).
Eigen::Isometry3d Scaled(const Eigen::Isometry3d& step, double scale) {
  if (scale == 1.0) return step;
  return ExpSe3(scale * LogSe3(step));
}

// The precedence of how a frame was placed along a chain from the reference.
MotionSource Worse(MotionSource a, MotionSource b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

}  // namespace

const char* ToString(MotionSource source) {
  switch (source) {
    case MotionSource::kRegistered:
      return "registered";
    case MotionSource::kChained:
      return "chained";
    case MotionSource::kPrior:
      return "prior";
  }
  return "unknown";
}

const char* ToString(FrameTracking tracking) {
  switch (tracking) {
    case FrameTracking::kRegistered:
      return "registered";
    case FrameTracking::kDense:
      return "dense";
    case FrameTracking::kBlind:
      return "blind";
  }
  return "unknown";
}

void SmoothedVelocity::Add(const Eigen::Isometry3d& step, double dt_s) {
  SIGHTMAP_CHECK(dt_s > 0.0, "a velocity needs a positive time step");
  const Eigen::Matrix<double, 6, 1> velocity = LogSe3(step) / dt_s;
  velocity_ = has_velocity_ ? velocity_ + kVelocityWeight * (velocity - velocity_) : velocity;
  has_velocity_ = true;
}

Eigen::Isometry3d SmoothedVelocity::Step(double dt_s) const { return ExpSe3(velocity_ * dt_s); }

bool TrackerOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!CheckOrbFeatures(features, error) || !registration.Check(error) ||
      !dense_rescue.Check(error) || !dense_search.Check(error)) {
    return false;
  }
  if (!(keyframe_rate_hz >= 0.0) || !std::isfinite(keyframe_rate_hz) || keyframe_rate_hz > 1000) {
    return fail("keyframe_rate_hz must be in [0, 1000] (0 makes every frame a keyframe)");
  }
  if (!(min_reference_inlier_ratio >= 0.0 && min_reference_inlier_ratio <= 1.0)) {
    return fail("min_reference_inlier_ratio must be in [0, 1]");
  }
  if (!(max_deviation_mps > 0.0) || !(max_deviation_dps > 0.0) || !(deviation_slack_m >= 0.0) ||
      !(deviation_slack_deg >= 0.0)) {
    return fail("the deviation bounds must be positive and the slacks not negative");
  }
  if (!(min_keyframe_interval_s >= 0.0)) return fail("min_keyframe_interval_s must be >= 0");
  if (!(richer_reference_ratio >= 1.0)) return fail("richer_reference_ratio must be >= 1");
  if (depth_downscale < 1) return fail("depth_downscale must be at least 1");
  if (!dense.Check(error)) return false;
  if (!(dense_max_interval_s > 0.0)) return fail("dense_max_interval_s must be positive");
  if (!(dense_max_deviation_mps > 0.0) || !(dense_max_deviation_dps > 0.0) ||
      !(dense_slack_m >= 0.0) || !(dense_slack_deg >= 0.0)) {
    return fail("the dense deviation bounds must be positive and the slacks not negative");
  }
  if (!(dense_max_speed_mps > 0.0) || !(dense_max_turn_rate_dps > 0.0)) {
    return fail("dense_max_speed_mps and dense_max_turn_rate_dps must be positive");
  }
  if (!(dense_step_sigma_m > 0.0) || !(dense_step_sigma_rad > 0.0) ||
      !(dense_search_sigma_rad > 0.0) || !(prior_sigma_m > 0.0) || !(prior_sigma_mps >= 0.0) ||
      !(prior_sigma_rad > 0.0) || !(prior_sigma_radps >= 0.0)) {
    return fail("the dense step and prior sigmas must be positive");
  }
  if (!(dense_weak_eigen_ratio >= 0.0 && dense_weak_eigen_ratio <= 1.0) ||
      !(dense_weak_lever_m > 0.0)) {
    return fail("dense_weak_eigen_ratio must be in [0, 1] and dense_weak_lever_m positive");
  }
  if (!(blind_keyframe_after_s >= 0.0)) return fail("blind_keyframe_after_s must be >= 0");
  if (!(blind_velocity_decay >= 0.0 && blind_velocity_decay <= 1.0)) {
    return fail("blind_velocity_decay must be in [0, 1]");
  }
  if (min_reference_points < 0) return fail("min_reference_points must not be negative");
  if (!(start_max_wait_s >= 0.0)) return fail("start_max_wait_s must be >= 0");
  return true;
}

struct Tracker::Placed {
  RgbdFrame frame;
  Features features;
  cv::Mat depth_small;
  int points = 0;  // keypoints with a 3D point
  // Pose in the reference keyframe's camera frame, its covariance, and how it was found.
  Eigen::Isometry3d reference_from_cam = Eigen::Isometry3d::Identity();
  Matrix6 covariance = Matrix6::Zero();
  MotionSource source = MotionSource::kRegistered;
  int inliers = 0;
  int near_inliers = 0;  // of `inliers`, within RegistrationOptions::near_depth_m
  double blind_s = 0.0;
  Matrix6 blind_start_covariance = Matrix6::Zero();  // the covariance when the blind time began
  // Prepared for dense alignment when first needed (Tracker::DenseOf), shared by the copies.
  std::shared_ptr<DenseAligner::Frame> dense;
};

namespace {

capture::KeyframeSamplerOptions RateOf(const TrackerOptions& options) {
  capture::KeyframeSamplerOptions rate;
  rate.rate_hz = options.keyframe_rate_hz;
  return rate;
}

}  // namespace

Tracker::Tracker(const Intrinsics& camera, const TrackerOptions& options)
    : camera_(camera), options_(options), rate_(RateOf(options)), aligner_(camera, options.dense) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  SIGHTMAP_CHECK_OPTIONS(camera_);
  SIGHTMAP_CHECK(
      camera_.width % options_.depth_downscale == 0 &&
          camera_.height % options_.depth_downscale == 0,
      "the depth downscale must divide the " << camera_.width << "x" << camera_.height << " image");
}

Tracker::~Tracker() = default;

Tracker::Placed Tracker::Prepare(const RgbdFrame& frame, TrackResult* result) const {
  if (frame.color.type() != CV_8UC3 || frame.color.cols != camera_.width ||
      frame.color.rows != camera_.height) {
    SIGHTMAP_THROW(InvalidArgument, "a tracked frame's colour must be 8-bit BGR of "
                                        << camera_.width << "x" << camera_.height);
  }
  if (frame.depth.type() != CV_16UC1 || frame.depth.size() != frame.color.size()) {
    SIGHTMAP_THROW(InvalidArgument,
                   "a tracked frame's depth must be 16-bit [mm] of the colour image's size");
  }
  const Clock::time_point start = Clock::now();
  Placed placed;
  placed.frame = frame;
  placed.features = ExtractFeatures(frame.color, frame.depth, camera_, options_.features);
  placed.points = static_cast<int>(placed.features.NumPoints());
  cv::resize(
      frame.depth, placed.depth_small,
      cv::Size(camera_.width / options_.depth_downscale, camera_.height / options_.depth_downscale),
      0.0, 0.0, cv::INTER_NEAREST);
  result->features_s = SecondsSince(start);
  return placed;
}

bool Tracker::RegisterToReference(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                                  TrackResult* result) {
  const Clock::time_point start = Clock::now();
  RegistrationResult registration =
      RegisterRgbd(frame.features, reference_->features, frame.depth_small, reference_->depth_small,
                   camera_, options_.registration, &predicted);
  result->registration_s += SecondsSince(start);
  bool rescued = false;
  const bool was_accepted = registration.success;
  if (dt_s > options_.dense_max_interval_s &&
      NeedsDenseAlignment(registration, options_.dense_rescue)) {
    const Clock::time_point rescue_start = Clock::now();
    registration = RescueByDenseAlignment(
        registration, aligner_, DenseOf(frame), DenseOf(*reference_), frame.depth_small,
        reference_->depth_small, camera_, options_.registration, options_.dense_rescue);
    rescued = registration.success && !was_accepted;
    result->dense_s += SecondsSince(rescue_start);
  }
  // The prediction is good to the time since the last frame registration or ICP placed.
  if (!Believable(registration, predicted, dt_s + last_->blind_s)) return false;
  if (rescued) ++counters_.rescued;
  reference_best_inliers_ = std::max(reference_best_inliers_, registration.inliers);
  reference_best_near_inliers_ = std::max(reference_best_near_inliers_, registration.near_inliers);
  frame.reference_from_cam = registration.target_from_source;
  frame.covariance = Inverse(registration.information);
  frame.source = MotionSource::kRegistered;
  frame.inliers = registration.inliers;
  frame.near_inliers = registration.near_inliers;
  frame.blind_s = 0.0;
  result->inliers = registration.inliers;
  return true;
}

bool Tracker::Believable(const RegistrationResult& registration, const Eigen::Isometry3d& predicted,
                         double since_placed_s) const {
  return registration.success && registration.target_from_source.matrix().allFinite() &&
         registration.information.allFinite() &&
         MotionWithin(predicted.inverse() * registration.target_from_source,
                      options_.max_deviation_mps * since_placed_s + options_.deviation_slack_m,
                      options_.max_deviation_dps * since_placed_s + options_.deviation_slack_deg);
}

bool Tracker::RegisterDensely(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                              TrackResult* result) {
  const Clock::time_point start = Clock::now();
  // In a dense chain each frame is aligned twice, as the source and then as the target (last_),
  // and prepared once.
  DenseAligner::Frame& last = DenseOf(*last_);
  DenseAligner::Frame& current = DenseOf(frame);
  // Predicted step from the last frame: last_from_cam.
  const Eigen::Isometry3d step_guess = last_->reference_from_cam.inverse() * predicted;
  const DenseAlignment aligned = aligner_.Align(current, last, step_guess);
  if (!aligned.success) {
    result->dense_s = SecondsSince(start);
    return false;
  }
  Eigen::Isometry3d step =
      !registered_velocity_.empty()
          ? KeepPriorWhereWeak(aligned.target_from_source, aligned.information,
                               registered_velocity_.Step(dt_s), options_.dense_weak_eigen_ratio,
                               options_.dense_weak_lever_m)
          : aligned.target_from_source;
  // A step that fits the two frames worse than standing still, in every respect (fewer paired
  // pixels, larger depth and grey residuals), is not a motion the images show: before a bare
  // projection screen OpenCV's alignment, started from the approach's velocity, slid and turned
  // while the frames agreed best unmoved, and the survey's standstill keyframes there ended 8-23
  // degrees off.
  const bool at_rest = options_.dense_prefer_rest && StandingStillFitsBetter(current, last, step);
  if (at_rest) step = Eigen::Isometry3d::Identity();
  result->dense_s = SecondsSince(start);
  const Eigen::Isometry3d deviation = step_guess.inverse() * step;
  if (!MotionWithin(deviation, options_.dense_max_deviation_mps * dt_s + options_.dense_slack_m,
                    options_.dense_max_deviation_dps * dt_s + options_.dense_slack_deg) ||
      !MotionWithin(step, options_.dense_max_speed_mps * dt_s + options_.dense_slack_m,
                    options_.dense_max_turn_rate_dps * dt_s + options_.dense_slack_deg)) {
    return false;
  }
  if (at_rest) ++counters_.dense_at_rest;
  frame.reference_from_cam = Orthonormalised(last_->reference_from_cam * step);
  frame.covariance = last_->covariance +
                     DiagonalCovariance(options_.dense_step_sigma_m, options_.dense_step_sigma_rad);
  frame.source = Worse(last_->source, MotionSource::kChained);
  frame.blind_s = last_->blind_s;
  frame.blind_start_covariance = last_->blind_start_covariance;
  return true;
}

bool Tracker::SearchDensely(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s,
                            TrackResult* result) {
  if (!options_.dense_search.enabled) return false;
  const Clock::time_point start = Clock::now();
  const Eigen::Isometry3d step_guess = last_->reference_from_cam.inverse() * predicted;
  const std::optional<DenseSearchResult> found = SearchByDenseAlignment(
      step_guess, aligner_, DenseOf(frame), DenseOf(*last_), frame.depth_small, last_->depth_small,
      camera_, options_.registration, options_.dense_rescue, options_.dense_search);
  result->dense_s += SecondsSince(start);
  if (!found) return false;
  const Eigen::Isometry3d step = found->target_from_source;
  if (!MotionWithin(step, options_.dense_max_speed_mps * dt_s + options_.dense_slack_m,
                    options_.dense_max_turn_rate_dps * dt_s + options_.dense_slack_deg)) {
    return false;
  }
  ++counters_.searched;
  // Chained, not registered: the mapper neither refines it nor bridges a blind run from it.
  frame.source = Worse(last_->source, MotionSource::kChained);
  frame.reference_from_cam = Orthonormalised(last_->reference_from_cam * step);
  frame.covariance = last_->covariance +
                     DiagonalCovariance(options_.prior_sigma_m + options_.prior_sigma_mps * dt_s,
                                        options_.dense_search_sigma_rad);
  frame.blind_s = last_->blind_s;
  frame.blind_start_covariance = last_->blind_start_covariance;
  return true;
}

DenseImage Tracker::DenseImageOf(const RgbdFrame& frame) const {
  return MakeDenseImage(frame.color, frame.depth, camera_, options_.dense);
}

DenseAligner::Frame& Tracker::DenseOf(Placed& placed) const {
  if (!placed.dense) placed.dense = aligner_.Prepare(DenseImageOf(placed.frame));
  return *placed.dense;
}

bool Tracker::StandingStillFitsBetter(DenseAligner::Frame& current, DenseAligner::Frame& last,
                                      const Eigen::Isometry3d& last_from_current) const {
  const DenseFit moved = aligner_.Fit(current, last, last_from_current);
  const DenseFit rest = aligner_.Fit(current, last, Eigen::Isometry3d::Identity());
  return rest.pairs >= moved.pairs && rest.normalised_rms <= moved.normalised_rms &&
         rest.intensity_rms <= moved.intensity_rms;
}

void Tracker::PlaceBlind(Placed& frame, const Eigen::Isometry3d& predicted, double dt_s) const {
  frame.reference_from_cam = predicted;
  frame.source = MotionSource::kPrior;
  frame.blind_s = last_->blind_s + dt_s;
  frame.blind_start_covariance =
      last_->blind_s > 0.0 ? last_->blind_start_covariance : last_->covariance;
  frame.covariance =
      frame.blind_start_covariance +
      DiagonalCovariance(options_.prior_sigma_m + options_.prior_sigma_mps * frame.blind_s,
                         options_.prior_sigma_rad + options_.prior_sigma_radps * frame.blind_s);
}

void Tracker::Emit(Placed& frame, bool early, TrackResult* result) {
  TrackedKeyframe keyframe;
  keyframe.frame = frame.frame;
  keyframe.features = frame.features;
  keyframe.depth_small = frame.depth_small;
  if (reference_) {
    KeyframeMotion motion;
    motion.source = frame.source;
    motion.previous_from_cam = Orthonormalised(frame.reference_from_cam);
    motion.information = Inverse(frame.covariance);
    motion.inliers = frame.source == MotionSource::kRegistered ? frame.inliers : 0;
    motion.blind_s = frame.blind_s;
    keyframe.motion = motion;
    if (motion.source == MotionSource::kPrior) ++counters_.prior_keyframes;
  }
  result->keyframes.push_back(std::move(keyframe));
  ++counters_.keyframes;
  if (early) ++counters_.early_keyframes;
  // The keyframe is the new reference: poses are now relative to it, and exact.
  frame.reference_from_cam = Eigen::Isometry3d::Identity();
  frame.covariance = Matrix6::Zero();
  frame.source = MotionSource::kRegistered;
  frame.inliers = 0;
  frame.blind_s = 0.0;
  frame.blind_start_covariance = Matrix6::Zero();
  reference_ = std::make_unique<Placed>(frame);
  reference_best_inliers_ = 0;
  reference_best_near_inliers_ = 0;
}

FrameTracking Tracker::Place(Placed& frame, double dt_s, TrackResult* result) {
  // Constant velocity, scaled to this frame's interval when the stream skipped frames, and fading
  // while nothing registers: one bad step extrapolated over a blind second turned the map by
  // 50 degrees, where standing still is off by the turn the walker really made.
  double scale = velocity_dt_s_ > 0.0 ? std::min(dt_s / velocity_dt_s_, 3.0) : 1.0;
  if (last_->source == MotionSource::kPrior) scale *= options_.blind_velocity_decay;
  Eigen::Isometry3d velocity = Scaled(velocity_, scale);
  Eigen::Isometry3d predicted = last_->reference_from_cam * velocity;

  bool registered = RegisterToReference(frame, predicted, dt_s, result);
  if (!registered && last_->frame.index != reference_->frame.index &&
      last_->source == MotionSource::kRegistered) {
    // The overlap with the reference is lost, but the last frame still had it: it becomes the
    // keyframe this frame registers to.
    Emit(*last_, true, result);
    predicted = velocity;
    registered = RegisterToReference(frame, predicted, dt_s, result);
  }
  // The last step may come from a registration that matched a repeated texture: the fallbacks
  // start from the registered frames' smoothed velocity instead (fallback_on_smoothed_velocity).
  if (!registered && options_.fallback_on_smoothed_velocity && !registered_velocity_.empty() &&
      last_->source == MotionSource::kRegistered && dt_s <= options_.dense_max_interval_s) {
    velocity = registered_velocity_.Step(dt_s);
    predicted = last_->reference_from_cam * velocity;
  }
  FrameTracking tracking = FrameTracking::kRegistered;
  if (registered) {
    registered_velocity_.Add(last_->reference_from_cam.inverse() * frame.reference_from_cam, dt_s);
  } else {
    const bool dense =
        dt_s <= options_.dense_max_interval_s
            ? options_.dense_fallback && RegisterDensely(frame, predicted, dt_s, result)
            : SearchDensely(frame, predicted, dt_s, result);
    tracking = dense ? FrameTracking::kDense : FrameTracking::kBlind;
    if (!dense) PlaceBlind(frame, predicted, dt_s);
  }
  result->tracking = tracking;
  switch (tracking) {
    case FrameTracking::kRegistered:
      ++counters_.registered;
      break;
    case FrameTracking::kDense:
      ++counters_.dense;
      break;
    case FrameTracking::kBlind:
      ++counters_.blind;
      break;
  }
  // A blind frame keeps the faded prediction as the velocity.
  velocity_ = tracking == FrameTracking::kBlind
                  ? velocity
                  : last_->reference_from_cam.inverse() * frame.reference_from_cam;
  velocity_dt_s_ = dt_s;
  return tracking;
}

bool Tracker::WantsEarlyKeyframe(const Placed& frame, FrameTracking tracking) const {
  const double since_keyframe_s =
      1e-9 * static_cast<double>(frame.frame.timestamp_ns - reference_->frame.timestamp_ns);
  const bool may_add_early = since_keyframe_s >= options_.min_keyframe_interval_s;
  const bool good_reference = frame.points >= options_.min_reference_points;
  switch (tracking) {
    case FrameTracking::kRegistered:
      return (frame.inliers < options_.min_reference_inlier_ratio * reference_best_inliers_ ||
              frame.near_inliers <
                  options_.min_reference_inlier_ratio * reference_best_near_inliers_ ||
              frame.points > options_.richer_reference_ratio * reference_->points) &&
             may_add_early;
    case FrameTracking::kDense:
      // Features may register to a frame the dense chain reached where not to the reference, but
      // a dense chain along a bare wall gains nothing from a keyframe every frame.
      return good_reference && since_keyframe_s >= options_.blind_keyframe_after_s;
    case FrameTracking::kBlind:
      return frame.blind_s >= options_.blind_keyframe_after_s && good_reference && may_add_early;
  }
  return false;
}

bool Tracker::StartOnEarlierFrame(Placed& frame, TrackResult* result) {
  if (counters_.frames == 1) first_timestamp_ns_ = frame.frame.timestamp_ns;
  const double waited_s =
      1e-9 * static_cast<double>(frame.frame.timestamp_ns - first_timestamp_ns_);
  const auto rich = [&](const Placed& placed) {
    return placed.points >= options_.min_reference_points;
  };
  const bool waited = waited_s >= options_.start_max_wait_s;
  // A rich frame anchors the map once the next frame registers to it: a rich first frame that
  // nothing after it registers to would hang the map on the motion model all the same. Past the
  // wait, the candidate still starts it when it is rich or richer than this frame (at 1 Hz the next
  // frame often does not register, and dropping a rich frame loses a second of the walk). An
  // earlier frame is placed now, and this frame is tracked against it.
  if (start_candidate_ &&
      (rich(*start_candidate_) ? waited || RegistersTo(frame, *start_candidate_)
                               : waited && start_candidate_->points > frame.points)) {
    --counters_.before_start;
    StartMapOn(*start_candidate_, result);
    return true;
  }
  if (waited) {
    StartMapOn(frame, result);
    return false;
  }
  // Waiting: the newest rich frame, else the richest, is the candidate.
  if (!start_candidate_ || rich(frame) ||
      (!rich(*start_candidate_) && frame.points > start_candidate_->points)) {
    start_candidate_ = std::make_unique<Placed>(frame);
  }
  ++counters_.before_start;
  return false;
}

bool Tracker::RegistersTo(const Placed& frame, const Placed& reference) const {
  const RegistrationResult registration =
      RegisterRgbd(frame.features, reference.features, frame.depth_small, reference.depth_small,
                   camera_, options_.registration);
  const double dt_s =
      1e-9 * static_cast<double>(frame.frame.timestamp_ns - reference.frame.timestamp_ns);
  return Believable(registration, Eigen::Isometry3d::Identity(), dt_s);
}

void Tracker::StartMapOn(Placed& first, TrackResult* result) {
  Emit(first, false, result);
  last_ = std::make_unique<Placed>(first);
  ++counters_.registered;
  start_candidate_.reset();
}

TrackResult Tracker::Finish() {
  TrackResult result;
  if (!reference_ && start_candidate_) {
    --counters_.before_start;
    StartMapOn(*start_candidate_, &result);
  }
  return result;
}

void Tracker::ContinueFrom(const RgbdFrame& keyframe) {
  SIGHTMAP_CHECK(!reference_ && counters_.frames == 0,
                 "a tracker continues a walk only before its first frame");
  TrackResult ignored;
  Placed frame = Prepare(keyframe, &ignored);
  rate_.Accept(keyframe.timestamp_ns);  // the grid goes on after the stored keyframe
  reference_ = std::make_unique<Placed>(frame);
  last_ = std::make_unique<Placed>(std::move(frame));
}

TrackResult Tracker::Track(const RgbdFrame& input) {
  const Clock::time_point start = Clock::now();
  TrackResult result;
  Placed frame = Prepare(input, &result);
  ++counters_.frames;
  const bool tick = rate_.Accept(input.timestamp_ns);
  if (!reference_ && !StartOnEarlierFrame(frame, &result)) {
    // Still waiting, or the map starts on this frame, which is then its own reference.
    if (reference_) result.reference_index = reference_->frame.index;
    result.total_s = SecondsSince(start);
    return result;
  }
  const double dt_s =
      std::max(1e-3, 1e-9 * static_cast<double>(input.timestamp_ns - last_->frame.timestamp_ns));
  const FrameTracking tracking = Place(frame, dt_s, &result);
  const bool early = WantsEarlyKeyframe(frame, tracking);
  if (tick || early) Emit(frame, !tick, &result);
  result.reference_index = reference_->frame.index;
  result.reference_from_cam = frame.reference_from_cam;
  last_ = std::make_unique<Placed>(std::move(frame));
  result.total_s = SecondsSince(start);
  return result;
}

SIGHTMAP_OPTIONS_JSON(TrackerOptions, features, registration, keyframe_rate_hz,
                      min_reference_inlier_ratio, richer_reference_ratio, min_keyframe_interval_s,
                      depth_downscale, max_deviation_mps, max_deviation_dps, deviation_slack_m,
                      deviation_slack_deg, dense_fallback, dense_max_interval_s, dense,
                      dense_max_deviation_mps, dense_max_deviation_dps, dense_slack_m,
                      dense_slack_deg, dense_max_speed_mps, dense_max_turn_rate_dps,
                      dense_step_sigma_m, dense_step_sigma_rad, dense_weak_eigen_ratio,
                      dense_weak_lever_m, dense_prefer_rest, fallback_on_smoothed_velocity,
                      dense_rescue, dense_search, dense_search_sigma_rad, prior_sigma_m,
                      prior_sigma_mps, prior_sigma_rad, prior_sigma_radps, blind_velocity_decay,
                      blind_keyframe_after_s, min_reference_points, start_max_wait_s)

std::optional<Eigen::Isometry3d> TrackedChain::Add(const TrackResult& result) {
  for (const TrackedKeyframe& keyframe : result.keyframes) {
    world_from_newest_ =
        keyframe.motion && world_from_newest_
            ? *world_from_newest_ * keyframe.motion->previous_from_cam
            : keyframe.frame.world_from_cam_gt.value_or(Eigen::Isometry3d::Identity());
    newest_index_ = keyframe.frame.index;
  }
  if (!world_from_newest_) return std::nullopt;
  SIGHTMAP_CHECK(result.reference_index == newest_index_,
                 "frame placed relative to keyframe "
                     << result.reference_index << ", not the newest one (" << newest_index_ << ")");
  return *world_from_newest_ * result.reference_from_cam;
}

}  // namespace sightmap::slam
