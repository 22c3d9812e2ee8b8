// The mapper on the synthetic building at 1 Hz, against the simulator's ground truth.
#include "slam/mapper.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "core/statistics.h"
#include "sim/simulator.h"
#include "slam/sim_walk_testing.h"
#include "slam/tracker.h"
#include "slam/trajectory_eval.h"

namespace sightmap::slam {
namespace {

using Walk = testing::SimWalk;

// 9 s of the handheld walk at 5 Hz, rendered once for all tests of this file. These tests check
// the mapper's logic on frames registration can bridge; how it fares at 1 Hz over a whole walk
// (where it still loses tracking on bare walls) is measured by slam_benchmark.
const Walk& HandheldWalkAt5Hz() {
  static const Walk* walk = [] {
    sim::SimulatorOptions options;
    options.fps = 5.0;
    options.frames = 48;
    // From 0.6 s in: session 1 starts facing a bare wall at arm's length while turning away.
    return new Walk(testing::RenderSimWalk(options, 3));
  }();
  return *walk;
}

MapperOptions SmallVocabulary() {
  MapperOptions options;
  options.vocabulary_training_keyframes = 15;
  return options;
}

TEST(Mapper, TracksTheHandheldWalkWithCentimetreAccuracy) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, SmallVocabulary());
  std::vector<StampedPose> ground_truth;
  int lost = 0;
  for (const RgbdFrame& frame : walk.frames) {
    const KeyframeReport report = mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
    if (report.state == TrackingState::kLost) ++lost;
    ground_truth.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
  }
  ASSERT_EQ(mapper.NumKeyframes(), walk.frames.size());
  EXPECT_EQ(lost, 0);
  EXPECT_EQ(mapper.NumSegments(), 1);
  ASSERT_NE(mapper.vocabulary(), nullptr);
  const TrajectoryError error = EvaluateTrajectory(ground_truth, mapper.Trajectory());
  std::printf("handheld, %zu keyframes: ATE rmse %.4f m, max %.4f m, %d loops\n",
              walk.frames.size(), error.ate_rmse_m, error.ate_max_m, mapper.NumLoopClosures());
  EXPECT_LT(error.ate_rmse_m, 0.05);

  // Every accepted loop agrees with the ground truth.
  for (const MapperLink& link : mapper.Links()) {
    const Eigen::Isometry3d truth =
        walk.frames[static_cast<size_t>(link.from)].world_from_cam_gt->inverse() *
        *walk.frames[static_cast<size_t>(link.to)].world_from_cam_gt;
    const Eigen::Isometry3d off = truth.inverse() * link.to_in_from;
    if (!link.active) continue;
    EXPECT_LT(off.translation().norm(), 0.10) << link.from << " -> " << link.to;
    EXPECT_LT(RotationAngleDeg(off), 3.0) << link.from << " -> " << link.to;
  }
}

struct MappedWalk {
  std::vector<StampedPose> ground_truth;
  std::vector<StampedPose> trajectory;
  int loops = 0;
  int local_optimisations = 0;
  int optimisations = 0;
  // After Mapper::OptimiseWhole, and how far a second call moved any keyframe [m].
  std::vector<StampedPose> settled;
  double settled_again_m = 0.0;
};

// The furthest any keyframe lies from where it lies in the other trajectory (same keyframes) [m].
double LargestMoveM(const std::vector<StampedPose>& a, const std::vector<StampedPose>& b) {
  EXPECT_EQ(a.size(), b.size());
  double largest = 0.0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    largest = std::max(
        largest, (a[i].world_from_cam.translation() - b[i].world_from_cam.translation()).norm());
  }
  return largest;
}

// The walk there and back again (the way back closes loops with the way there), checking that
// an optimisation kept local moved only the keyframes it reports.
MappedWalk ThereAndBack(const Walk& walk, const MapperOptions& options) {
  std::vector<const RgbdFrame*> frames;
  for (const RgbdFrame& frame : walk.frames) frames.push_back(&frame);
  for (auto it = walk.frames.rbegin(); it != walk.frames.rend(); ++it) frames.push_back(&*it);
  Mapper mapper(walk.camera, options);
  MappedWalk mapped;
  for (size_t i = 0; i < frames.size(); ++i) {
    const TimestampNs timestamp_ns = 1'000'000'000 + static_cast<TimestampNs>(i) * 200'000'000;
    const std::vector<StampedPose> before = mapper.Trajectory();
    const KeyframeReport report =
        mapper.AddKeyframe(timestamp_ns, frames[i]->color, frames[i]->depth);
    mapped.ground_truth.push_back({timestamp_ns, *frames[i]->world_from_cam_gt});
    if (!report.optimised) continue;
    ++(report.optimised_locally ? mapped.local_optimisations : mapped.optimisations);
    if (!report.optimised_locally) continue;
    EXPECT_FALSE(report.moved.empty());
    // The new keyframe and some of the others: at least one was held.
    EXPECT_LE(report.moved.size(), before.size()) << "keyframe " << report.id;
    for (size_t id = 0; id < before.size(); ++id) {
      if (std::find(report.moved.begin(), report.moved.end(), static_cast<int64_t>(id)) !=
          report.moved.end()) {
        continue;
      }
      EXPECT_TRUE(
          mapper.WorldFromCam(static_cast<int64_t>(id)).isApprox(before[id].world_from_cam, 0.0))
          << "keyframe " << id << " moved but is not reported";
    }
  }
  mapped.trajectory = mapper.Trajectory();
  mapped.loops = mapper.NumLoopClosures();
  const KeyframeReport whole = mapper.OptimiseWhole();
  EXPECT_TRUE(whole.optimised);
  EXPECT_EQ(whole.id, static_cast<int64_t>(frames.size()) - 1);
  mapped.settled = mapper.Trajectory();
  mapper.OptimiseWhole();
  mapped.settled_again_m = LargestMoveM(mapper.Trajectory(), mapped.settled);
  for (const MapperLink& link : mapper.Links()) {
    if (!link.active || link.type != LinkType::kLoopClosure) continue;
    const Eigen::Isometry3d truth =
        frames[static_cast<size_t>(link.from)]->world_from_cam_gt->inverse() *
        *frames[static_cast<size_t>(link.to)]->world_from_cam_gt;
    const Eigen::Isometry3d off = truth.inverse() * link.to_in_from;
    EXPECT_LT(off.translation().norm(), 0.10) << "loop " << link.from << " -> " << link.to;
    EXPECT_LT(RotationAngleDeg(off), 3.0) << "loop " << link.from << " -> " << link.to;
  }
  return mapped;
}

TEST(Mapper, LoopsThatFitTheMapMoveOnlyTheKeyframesNearThem) {
  const Walk& walk = HandheldWalkAt5Hz();
  const MappedWalk local = ThereAndBack(walk, SmallVocabulary());
  MapperOptions whole_options = SmallVocabulary();
  whole_options.local_loop_hops = 0;
  const MappedWalk whole = ThereAndBack(walk, whole_options);
  ASSERT_GE(local.loops, 3);
  EXPECT_GE(local.local_optimisations, 1);
  EXPECT_EQ(whole.local_optimisations, 0);
  const double local_m = EvaluateTrajectory(local.ground_truth, local.trajectory).ate_rmse_m;
  const double whole_m = EvaluateTrajectory(whole.ground_truth, whole.trajectory).ate_rmse_m;
  std::printf("there and back, %d loops: %d optimised locally, ATE %.4f m (whole part: %.4f m)\n",
              local.loops, local.local_optimisations, local_m, whole_m);
  EXPECT_LT(std::abs(local_m - whole_m), 0.003);
  // What the windows left between them, settled by one optimisation of the whole part at the end:
  // it moves the map (the local loops did leave something), lands within a millimetre of where
  // optimising every loop over the whole part did, and a second call finds nothing to move.
  const double settled_m = EvaluateTrajectory(local.ground_truth, local.settled).ate_rmse_m;
  const double moved_m = LargestMoveM(local.settled, local.trajectory);
  std::printf("settled at the end: ATE %.4f m, keyframes moved up to %.4f m, then %.6f m\n",
              settled_m, moved_m, local.settled_again_m);
  EXPECT_GT(moved_m, 1e-4);
  EXPECT_LT(std::abs(settled_m - EvaluateTrajectory(whole.ground_truth, whole.settled).ate_rmse_m),
            0.001);
  EXPECT_LT(local.settled_again_m, 1e-4);
}

// Proximity alone (no bag of words): on the way back every keyframe is near where the graph put
// the way there, and the loops it closes are the true ones. Dense refinement is off so that the
// odometry drifts for the loops to correct: with it, this short walk's odometry alone is within
// 1-2 mm.
TEST(Mapper, ProximityClosesLoopsThePlaceIndexIsNotAskedFor) {
  const Walk& walk = HandheldWalkAt5Hz();
  MapperOptions options = SmallVocabulary();
  options.loop_candidates = 0;
  options.dense_refinement = false;
  const MappedWalk nearby = ThereAndBack(walk, options);
  options.proximity_candidates = 0;
  const MappedWalk none = ThereAndBack(walk, options);
  EXPECT_EQ(none.loops, 0);
  EXPECT_GE(nearby.loops, 5);
  const double nearby_m = EvaluateTrajectory(nearby.ground_truth, nearby.trajectory).ate_rmse_m;
  const double none_m = EvaluateTrajectory(none.ground_truth, none.trajectory).ate_rmse_m;
  std::printf("there and back by proximity: %d loops, ATE %.4f m (without: %.4f m)\n", nearby.loops,
              nearby_m, none_m);
  // Measured: 4.2 mm with the loops, 8.6 mm without.
  EXPECT_LT(nearby_m, 0.6 * none_m);
}

// The median translation error of the mapper's odometry links against the ground truth [m].
double MedianOdometryLinkError(const Walk& walk, const MapperOptions& options) {
  Mapper mapper(walk.camera, options);
  for (const RgbdFrame& frame : walk.frames) {
    mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
  }
  std::vector<double> errors;
  for (const MapperLink& link : mapper.Links()) {
    if (link.type != LinkType::kOdometry) continue;
    const Eigen::Isometry3d truth =
        walk.frames[static_cast<size_t>(link.from)].world_from_cam_gt->inverse() *
        *walk.frames[static_cast<size_t>(link.to)].world_from_cam_gt;
    errors.push_back((truth.inverse() * link.to_in_from).translation().norm());
  }
  return Percentile(errors, 0.5);
}

// Frames 0-12 of the walk as the tracker emits them, every frame a keyframe.
std::vector<TrackedKeyframe> TrackedKeyframes0To12() {
  const Walk& walk = HandheldWalkAt5Hz();
  TrackerOptions tracker_options;
  tracker_options.keyframe_rate_hz = 0.0;  // every frame a keyframe
  Tracker tracker(walk.camera, tracker_options);
  std::vector<TrackedKeyframe> keyframes;
  for (size_t i = 0; i <= 12; ++i) {
    for (TrackedKeyframe& keyframe : tracker.Track(walk.frames[i]).keyframes) {
      keyframes.push_back(std::move(keyframe));
    }
  }
  SIGHTMAP_CHECK(keyframes.size() == 13, "the tracker makes every frame a keyframe");
  return keyframes;
}

// A tracked keyframe's motion made the motion model's guess after `blind_s` seconds blind.
void MakeBlind(double blind_s, const Eigen::Isometry3d& guess,
               const Eigen::Matrix<double, 6, 6>& information, KeyframeMotion* motion) {
  motion->source = MotionSource::kPrior;
  motion->blind_s = blind_s;
  motion->previous_from_cam = guess;
  motion->information = information;
}

// Keyframes 0-12 of the walk as the tracker emits them, keyframe 12 as if the tracker had placed
// it on its motion model 0.2 s blind, with a prediction `prediction_error_m` off sideways. The
// mapper still registers it to keyframe 10; returns whether that link was kept, and the error of
// the keyframe's pose relative to keyframe 11 [m].
bool KeepsABlindKeyframesLink(double prediction_error_m, double* pose_error_m) {
  const Walk& walk = HandheldWalkAt5Hz();
  MapperOptions options = SmallVocabulary();
  options.vocabulary_training_keyframes = 1000;  // links only
  Mapper mapper(walk.camera, options);
  std::vector<TrackedKeyframe> keyframes = TrackedKeyframes0To12();
  const Eigen::Isometry3d true_11_from_12 =
      walk.frames[11].world_from_cam_gt->inverse() * *walk.frames[12].world_from_cam_gt;
  MakeBlind(0.2, Eigen::Translation3d(prediction_error_m, 0.0, 0.0) * true_11_from_12,
            Eigen::Matrix<double, 6, 6>::Identity(), &*keyframes[12].motion);
  for (TrackedKeyframe& keyframe : keyframes) mapper.AddTrackedKeyframe(std::move(keyframe));
  const Eigen::Isometry3d mapped_11_from_12 =
      mapper.WorldFromCam(11).inverse() * mapper.WorldFromCam(12);
  *pose_error_m = (true_11_from_12.translation() - mapped_11_from_12.translation()).norm();
  return std::any_of(mapper.Links().begin(), mapper.Links().end(), [](const MapperLink& link) {
    return link.to == 12 && link.type == LinkType::kOdometry;
  });
}

TEST(Mapper, ABlindKeyframeKeepsOnlyLinksAWalkerCouldMake) {
  // Within reach of the motion model (1 m/s x 0.2 s + 5 cm), the registration places the
  // keyframe; further off, the link is what a repeated desk gives, and the prior stands.
  double near_error_m = 0.0;
  EXPECT_TRUE(KeepsABlindKeyframesLink(0.15, &near_error_m));
  EXPECT_LT(near_error_m, 0.03);
  double far_error_m = 0.0;
  EXPECT_FALSE(KeepsABlindKeyframesLink(0.6, &far_error_m));
  EXPECT_NEAR(far_error_m, 0.6, 0.03);
}

// Keyframes 0-12 of the walk as the tracker emits them, keyframe 11 as if the tracker had placed
// it on its motion model 0.2 s blind, guessing no motion at all. Returns the link 10 -> 11 as
// the mapper holds it after keyframe 12 (whose motion was registered), and that keyframe's
// report.
MapperLink BlindLinkAfterTheNextKeyframe(double bridged_sigma_factor, double min_blind_step_s,
                                         KeyframeReport* report) {
  const Walk& walk = HandheldWalkAt5Hz();
  MapperOptions options = SmallVocabulary();
  options.vocabulary_training_keyframes = 1000;  // links only
  options.bridged_sigma_factor = bridged_sigma_factor;
  options.bridge_min_blind_step_s = min_blind_step_s;
  Mapper mapper(walk.camera, options);
  std::vector<TrackedKeyframe> keyframes = TrackedKeyframes0To12();
  SIGHTMAP_CHECK(keyframes[10].motion->source == MotionSource::kRegistered &&
                     keyframes[12].motion->source == MotionSource::kRegistered,
                 "keyframes 10 and 12 register");
  MakeBlind(0.2, Eigen::Isometry3d::Identity(), DiagonalCovariance(0.08, 0.14).inverse(),
            &*keyframes[11].motion);
  for (TrackedKeyframe& keyframe : keyframes)
    *report = mapper.AddTrackedKeyframe(std::move(keyframe));
  for (const MapperLink& link : mapper.Links()) {
    if (link.from == 10 && link.to == 11 && link.type == LinkType::kPrior) return link;
  }
  ADD_FAILURE() << "no prior link 10 -> 11";
  return MapperLink();
}

TEST(Mapper, ABlindKeyframesLinkIsBridgedOnceTheMotionAfterItIsMeasured) {
  const Walk& walk = HandheldWalkAt5Hz();
  const Eigen::Isometry3d true_10_from_11 =
      walk.frames[10].world_from_cam_gt->inverse() * *walk.frames[11].world_from_cam_gt;
  KeyframeReport report;
  const MapperLink bridged = BlindLinkAfterTheNextKeyframe(0.5, 0.15, &report);
  const double bridged_error_m =
      (true_10_from_11.inverse() * bridged.to_in_from).translation().norm();
  const double step_m = true_10_from_11.translation().norm();
  std::printf("blind step of %.3f m: bridged %.4f m off\n", step_m, bridged_error_m);
  EXPECT_LT(bridged_error_m, 0.2 * step_m);
  EXPECT_LT(RotationAngleDeg(true_10_from_11.rotation(), bridged.to_in_from.rotation()), 1.0);
  ASSERT_EQ(report.id, 12);
  ASSERT_EQ(report.revised_links.size(), 1u);

  // Off, the guess stands: no motion, as the motion model had it.
  const MapperLink guessed = BlindLinkAfterTheNextKeyframe(0.0, 0.15, &report);
  EXPECT_NEAR(guessed.to_in_from.translation().norm(), 0.0, 1e-12);
  EXPECT_TRUE(report.revised_links.empty());
  // So it does for a step shorter than bridging asks (frames at the sensor's rate).
  const MapperLink short_step = BlindLinkAfterTheNextKeyframe(0.5, 0.25, &report);
  EXPECT_NEAR(short_step.to_in_from.translation().norm(), 0.0, 1e-12);
  EXPECT_TRUE(report.revised_links.empty());
  // Bridged, its deviations are halved: the information four times the motion model's.
  EXPECT_TRUE(bridged.information.isApprox(4.0 * guessed.information, 1e-9));
}

// Keyframes 0-12 of the walk as the tracker emits them, keyframe 12 as if the tracker had placed
// it on its motion model 0.2 s blind, guessing a 25 degree turn (about the image's vertical) that
// did not happen: beyond what a blind link may turn, so no registration replaces the guess.
// Returns how far keyframe 12's rotation is from the truth (relative to keyframe 0) once the
// map is optimised whole [deg].
double RotationErrorAfterAFalseBlindTurn(double manhattan_sigma_deg) {
  const Walk& walk = HandheldWalkAt5Hz();
  MapperOptions options = SmallVocabulary();
  options.vocabulary_training_keyframes = 1000;  // links only
  options.manhattan_sigma_deg = manhattan_sigma_deg;
  options.manhattan_max_deviation_deg = 30.0;
  Mapper mapper(walk.camera, options);
  std::vector<TrackedKeyframe> keyframes = TrackedKeyframes0To12();
  const Eigen::Isometry3d true_11_from_12 =
      walk.frames[11].world_from_cam_gt->inverse() * *walk.frames[12].world_from_cam_gt;
  const Eigen::Isometry3d false_turn(Eigen::AngleAxisd(DegToRad(25.0), Eigen::Vector3d::UnitY()));
  MakeBlind(0.2, true_11_from_12 * false_turn, DiagonalCovariance(0.08, 0.14).inverse(),
            &*keyframes[12].motion);
  for (TrackedKeyframe& keyframe : keyframes) mapper.AddTrackedKeyframe(std::move(keyframe));
  mapper.OptimiseWhole();
  const Eigen::Matrix3d true_0_from_12 =
      (walk.frames[0].world_from_cam_gt->inverse() * *walk.frames[12].world_from_cam_gt).linear();
  const Eigen::Matrix3d mapped_0_from_12 =
      (mapper.WorldFromCam(0).inverse() * mapper.WorldFromCam(12)).linear();
  std::printf("keyframes with the building's axes: %d of %zu\n", mapper.NumManhattanKeyframes(),
              mapper.NumKeyframes());
  return RotationAngleDeg(true_0_from_12, mapped_0_from_12);
}

// A keyframe placed blind turns with the guess; the building's axes in its depth turn it back.
TEST(Mapper, TheBuildingsAxesTurnBackAFalseBlindTurn) {
  const double without = RotationErrorAfterAFalseBlindTurn(0.0);
  const double with = RotationErrorAfterAFalseBlindTurn(1.0);
  std::printf("keyframe 12 after a false 25 degree turn: %.2f degrees off without, %.2f with\n",
              without, with);
  EXPECT_GT(without, 20.0);
  EXPECT_LT(with, 2.0);
}

// Keyframes 0-12 of the walk as the tracker emits them, keyframe 12's registered motion put
// `offset` off (as repeated texture puts features: a radiator's fins, a tiled box). Returns the
// error of the mapper's link 11 -> 12 against the truth [m].
double ErrorOfAMotionPutOff(const Eigen::Isometry3d& offset, const MapperOptions& options) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, options);
  std::vector<TrackedKeyframe> keyframes = TrackedKeyframes0To12();
  const Eigen::Isometry3d true_11_from_12 =
      walk.frames[11].world_from_cam_gt->inverse() * *walk.frames[12].world_from_cam_gt;
  KeyframeMotion& motion = *keyframes[12].motion;
  SIGHTMAP_CHECK(motion.source == MotionSource::kRegistered, "keyframe 12 registers");
  motion.previous_from_cam = offset * true_11_from_12;
  for (TrackedKeyframe& keyframe : keyframes) mapper.AddTrackedKeyframe(std::move(keyframe));
  for (const MapperLink& link : mapper.Links()) {
    if (link.from == 11 && link.to == 12) {
      return (true_11_from_12.inverse() * link.to_in_from).translation().norm();
    }
  }
  ADD_FAILURE() << "no link 11 -> 12";
  return 1.0;
}

TEST(Mapper, ARefinementTheFramesFitBetterCorrectsAMotionCentimetresOff) {
  // 8 cm sideways and 1.5 degrees: beyond the plain bound (5 cm), within the fit's (15 cm).
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = Eigen::AngleAxisd(DegToRad(1.5), Eigen::Vector3d::UnitY()).matrix();
  offset.translation() = Eigen::Vector3d(0.08, 0.0, 0.0);
  MapperOptions options = SmallVocabulary();
  options.vocabulary_training_keyframes = 1000;  // links only
  const double fitted_m = ErrorOfAMotionPutOff(offset, options);
  options.dense_fit_max_correction_m = 0.0;  // the plain bound alone
  const double bounded_m = ErrorOfAMotionPutOff(offset, options);
  std::printf("link 11 -> 12 put 8 cm off: %.4f m with the fit, %.4f m with the plain bound\n",
              fitted_m, bounded_m);
  EXPECT_LT(fitted_m, 0.01);
  EXPECT_GT(bounded_m, 0.07);
}

// The walk's keyframes as the tracker emits them (every frame), linked by their motions only;
// with `blind`, keyframes 10-29 as if the motion model had placed each after a second blind,
// with these sigmas (the tracker's prior after a blind second: 0.32 m and 0.62 rad,
// TrackerOptions::prior_*).
std::unique_ptr<Mapper> ChainedWalk(bool blind, double blind_sigma_m = 0.32,
                                    double blind_sigma_rad = 0.62) {
  const Walk& walk = HandheldWalkAt5Hz();
  TrackerOptions tracker_options;
  tracker_options.keyframe_rate_hz = 0.0;
  Tracker tracker(walk.camera, tracker_options);
  MapperOptions options = SmallVocabulary();
  options.vocabulary_training_keyframes = 1000;  // no loops of its own
  options.odometry_window = 1;                   // the motion the only link
  auto mapper = std::make_unique<Mapper>(walk.camera, options);
  for (const RgbdFrame& frame : walk.frames) {
    for (TrackedKeyframe& keyframe : tracker.Track(frame).keyframes) {
      const auto id = static_cast<int64_t>(mapper->NumKeyframes());
      if (blind && keyframe.motion && id >= 10 && id < 30) {
        keyframe.motion->source = MotionSource::kPrior;
        keyframe.motion->blind_s = 1.0;
        keyframe.motion->information = DiagonalCovariance(blind_sigma_m, blind_sigma_rad).inverse();
      }
      mapper->AddTrackedKeyframe(std::move(keyframe));
    }
  }
  return mapper;
}

// A loop from keyframe 0 to keyframe 40 (`offset` from where the graph has it, in keyframe 0's
// frame), measured to a centimetre.
MapperLink LoopOffTheGraph(const Mapper& mapper, const Eigen::Vector3d& offset) {
  MapperLink loop;
  loop.from = 0;
  loop.to = 40;
  loop.type = LinkType::kLoopClosure;
  loop.to_in_from =
      Eigen::Translation3d(offset) * (mapper.WorldFromCam(0).inverse() * mapper.WorldFromCam(40));
  loop.information = 1e4 * Eigen::Matrix<double, 6, 6>::Identity();
  return loop;
}

// A graph of registered links knows keyframe 40 relative to 0 to a few centimetres: a loop 3 or
// 10 m off matched a look-alike place, one 10 cm off is drift. The same walk hung on motion-model
// links for 20 seconds knows it only to metres, and a loop that far off may be the revisit.
TEST(Mapper, ALoopIsCheckedAgainstHowWellTheGraphKnowsItsEnds) {
  const std::unique_ptr<Mapper> registered_walk = ChainedWalk(false);
  const Mapper& registered = *registered_walk;
  ASSERT_GE(registered.NumKeyframes(), 41u);
  EXPECT_EQ(registered.NumPriorLinks(), 0);
  const double agrees = registered.LoopChi2(LoopOffTheGraph(registered, Eigen::Vector3d::Zero()));
  const double drift = registered.LoopChi2(LoopOffTheGraph(registered, {0.1, 0.0, 0.0}));
  const double far = registered.LoopChi2(LoopOffTheGraph(registered, {3.0, 0.0, 0.0}));
  const double next_room = registered.LoopChi2(LoopOffTheGraph(registered, {10.0, 0.0, 0.0}));
  const std::unique_ptr<Mapper> blind_walk = ChainedWalk(true);
  const Mapper& blind = *blind_walk;
  EXPECT_EQ(blind.NumPriorLinks(), 20);
  const double far_blind = blind.LoopChi2(LoopOffTheGraph(blind, {3.0, 0.0, 0.0}));
  std::printf(
      "loop 0 -> 40 chi-square: on the graph %.2f, 10 cm off %.2f, 3 m off %.1f, 10 m off "
      "%.0f; 3 m off after 20 blind seconds %.2f\n",
      agrees, drift, far, next_room, far_blind);
  const double limit = MapperOptions().loop_max_graph_chi2;
  EXPECT_LT(agrees, 1e-6);
  EXPECT_LT(drift, 1.0);
  EXPECT_GT(far, limit);
  EXPECT_GT(next_room, 10.0 * limit);
  EXPECT_LT(far_blind, 0.2 * limit);
}

// The check along the building's axes on a walk with 20 blind seconds (0.16 m and 5 degrees a
// link, as bridged ones between keyframes that see the axes): a loop that agrees with the
// measurements passes, one onto a look-alike room 10 m away does not. (Why it is needed beside
// the graph's check: AxesPath tests, and the 1 Hz robot walk in the README.)
TEST(Mapper, ALoopIsCheckedAlongTheAxes) {
  const std::unique_ptr<Mapper> walk = ChainedWalk(true, 0.16, DegToRad(5.0));
  const Mapper& mapper = *walk;
  ASSERT_EQ(mapper.NumPriorLinks(), 20);
  ASSERT_GT(mapper.NumManhattanKeyframes(), 20);
  const double agrees = mapper.LoopChi2AlongAxes(LoopOffTheGraph(mapper, Eigen::Vector3d::Zero()));
  const double drift = mapper.LoopChi2AlongAxes(LoopOffTheGraph(mapper, {0.3, 0.0, 0.0}));
  const double next_room = mapper.LoopChi2AlongAxes(LoopOffTheGraph(mapper, {10.0, 0.0, 0.0}));
  std::printf(
      "after 20 blind seconds, loop 0 -> 40 chi-square along the axes: on the graph %.2f, 30 cm "
      "off %.2f, 10 m off %.0f\n",
      agrees, drift, next_room);
  const double limit = MapperOptions().loop_max_axes_chi2;
  EXPECT_LT(agrees, 0.05 * limit);
  EXPECT_LT(drift, 0.1 * limit);
  EXPECT_GT(next_room, 2.0 * limit);
}

// A loop's error by ground truth [m] (the worst of translation and of rotation at 1 m), and
// whether the pose graph kept it.
struct LoopError {
  double error_m = 0.0;
  bool active = true;
};

// The tracker without its dense rescue: with it, frames 62-100 of seed 5's 1 Hz walk hold
// together well enough that the graph no longer keeps the look-alike below even unchecked, and the
// checks there need a loose graph.
TrackerOptions LooseTracker() {
  TrackerOptions options;
  options.dense_rescue.enabled = false;
  return options;
}

// The first 110 s of seed 5's walk given its 1 Hz frames, tracked and mapped as `sightmap map`
// does, and each loop the mapper accepted, by ground truth.
std::vector<LoopError> LoopErrorsOfSeed5At1Hz(const MapperOptions& options,
                                              const TrackerOptions& tracker_options) {
  static const Walk* walk = [] {
    sim::SimulatorOptions sim_options;
    sim_options.seed = 5;
    sim_options.fps = 1.0;
    sim_options.frames = 110;
    return new Walk(testing::RenderSimWalk(sim_options));
  }();
  Tracker tracker(walk->camera, tracker_options);
  Mapper mapper(walk->camera, options);
  std::vector<Eigen::Isometry3d> truths;  // by keyframe id
  const auto map = [&](std::vector<TrackedKeyframe> keyframes) {
    for (TrackedKeyframe& keyframe : keyframes) {
      truths.push_back(*keyframe.frame.world_from_cam_gt);
      mapper.AddTrackedKeyframe(std::move(keyframe));
    }
  };
  for (const RgbdFrame& frame : walk->frames) map(tracker.Track(frame).keyframes);
  map(tracker.Finish().keyframes);
  std::vector<LoopError> errors;
  for (const MapperLink& link : mapper.Links()) {
    if (link.type != LinkType::kLoopClosure) continue;
    const Eigen::Isometry3d truth =
        truths[static_cast<size_t>(link.from)].inverse() * truths[static_cast<size_t>(link.to)];
    const Eigen::Isometry3d error = truth.inverse() * link.to_in_from;
    errors.push_back(
        {std::max(error.translation().norm(), Eigen::AngleAxisd(error.linear()).angle()),
         link.active});
  }
  return errors;
}

// The worst error of the loops the map kept (active), or of all it accepted [m].
double WorstLoop(const std::vector<LoopError>& errors, bool kept_only) {
  double worst = 0.0;
  for (const LoopError& loop : errors) {
    if (loop.active || !kept_only) worst = std::max(worst, loop.error_m);
  }
  return worst;
}

// Seed 5's keyframe 100 stands in a room furnished like the one keyframe 62 saw 10 m away: place
// recognition proposes the pair and registration accepts it. In the graph the motion model's
// guesses hold loosely (blind runs not bridged), only the graph check keeps that loop out of the
// map: the graph knows where the two keyframes are to far better than 10 m. With the blind runs
// bridged, the pose graph switches it off even without the check, and the check along the
// building's axes alone refuses it before it is added.
TEST(Mapper, PlaceRecognitionRefusesALookAlikeRoomTheGraphPutsElsewhere) {
  MapperOptions unbridged;
  unbridged.bridged_sigma_factor = 0.0;
  MapperOptions unchecked_unbridged = unbridged;
  unchecked_unbridged.loop_max_graph_chi2 = 0.0;
  unchecked_unbridged.loop_max_axes_chi2 = 0.0;
  const std::vector<LoopError> loose = LoopErrorsOfSeed5At1Hz(unchecked_unbridged, LooseTracker());
  const std::vector<LoopError> checked = LoopErrorsOfSeed5At1Hz(unbridged, LooseTracker());
  std::printf(
      "unbridged: loops without the graph check %zu, worst kept %.2f m off; with it %zu, "
      "worst kept %.2f m\n",
      loose.size(), WorstLoop(loose, true), checked.size(), WorstLoop(checked, true));
  ASSERT_GT(WorstLoop(loose, true), 5.0)
      << "the test needs place recognition to propose the look-alike, and the graph to keep it";
  EXPECT_LT(WorstLoop(checked, true), 0.1);

  MapperOptions unchecked;
  unchecked.loop_max_graph_chi2 = 0.0;
  unchecked.loop_max_axes_chi2 = 0.0;
  const std::vector<LoopError> bridged = LoopErrorsOfSeed5At1Hz(unchecked, LooseTracker());
  MapperOptions along_the_axes_only = unchecked;
  along_the_axes_only.loop_max_axes_chi2 = MapperOptions().loop_max_axes_chi2;
  const std::vector<LoopError> axes_only =
      LoopErrorsOfSeed5At1Hz(along_the_axes_only, LooseTracker());
  std::printf("bridged, checked along the axes alone: %zu loops, worst %.2f m off\n",
              axes_only.size(), WorstLoop(axes_only, false));
  EXPECT_LT(WorstLoop(axes_only, false), 0.1) << "refused before it is added";
  const std::vector<LoopError> defaults = LoopErrorsOfSeed5At1Hz(MapperOptions(), LooseTracker());
  std::printf(
      "bridged: loops without the graph check %zu, worst %.2f m off, worst kept %.2f m; "
      "with it %zu, worst kept %.2f m\n",
      bridged.size(), WorstLoop(bridged, false), WorstLoop(bridged, true), defaults.size(),
      WorstLoop(defaults, true));
  EXPECT_GT(WorstLoop(bridged, false), 5.0) << "proposed and registered as before";
  EXPECT_LT(WorstLoop(bridged, true), 0.1) << "switched off by the pose graph";
  EXPECT_LT(WorstLoop(defaults, true), 0.1);
  // And as `sightmap map` tracks and maps by default.
  EXPECT_LT(WorstLoop(LoopErrorsOfSeed5At1Hz(MapperOptions(), TrackerOptions()), true), 0.1);
}

TEST(Mapper, DenseRefinementMakesTheOdometryLinksMillimetreAccurate) {
  const Walk& walk = HandheldWalkAt5Hz();
  MapperOptions features_only = SmallVocabulary();
  features_only.dense_refinement = false;
  const double features_m = MedianOdometryLinkError(walk, features_only);
  const double refined_m = MedianOdometryLinkError(walk, SmallVocabulary());
  std::printf("median odometry link error: features %.4f m, refined %.4f m\n", features_m,
              refined_m);
  EXPECT_LT(refined_m, 0.004);
  EXPECT_LT(refined_m, 0.6 * features_m);
}

TEST(Mapper, RelocalisesAfterAJumpAndJoinsTheSegments) {
  // The camera walks frames 0-29, then "teleports" back to where frame 10 was and walks on: a
  // second segment starts and is joined when the place is found.
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, SmallVocabulary());
  std::vector<size_t> order;
  for (size_t i = 0; i < 30; ++i) order.push_back(i);
  for (size_t i = 10; i < 25; ++i) order.push_back(i);
  bool relocalised = false;
  std::vector<StampedPose> ground_truth;
  for (size_t k = 0; k < order.size(); ++k) {
    const RgbdFrame& frame = walk.frames[order[k]];
    // Timestamps must stay unique and increasing for the evaluation.
    const TimestampNs t = static_cast<TimestampNs>(k) * 1'000'000'000;
    // The jump is announced (as an unregistrable one would start a segment by itself): 4 s back
    // along this walk happens to be close enough for odometry to bridge.
    if (k == 30) mapper.StartNewSegment();
    const KeyframeReport report = mapper.AddKeyframe(t, frame.color, frame.depth);
    relocalised = relocalised || report.state == TrackingState::kRelocalised;
    ground_truth.push_back({t, *frame.world_from_cam_gt});
  }
  EXPECT_TRUE(relocalised);
  EXPECT_EQ(mapper.NumSegments(), 1);
  EXPECT_EQ(mapper.NumKeyframes(), order.size());
  const TrajectoryError error = EvaluateTrajectory(ground_truth, mapper.Trajectory());
  std::printf("after relocalisation: ATE rmse %.4f m, max %.4f m\n", error.ate_rmse_m,
              error.ate_max_m);
  EXPECT_LT(error.ate_rmse_m, 0.05);
}

// Frames 0-29, four blank frames (the sensor covered: lost, and too many for odometry to reach
// back past), then frames 10-24 again, unannounced: to the mapper the walk went on. Returns the
// mapper's segments at the end and whether any keyframe was relocalised.
std::pair<int, bool> WalkBackAfterABlindGap(const MapperOptions& options, double* gap_s,
                                            double* jump_m) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, options);
  const cv::Mat black = cv::Mat::zeros(walk.frames[0].color.size(), walk.frames[0].color.type());
  const cv::Mat no_depth = cv::Mat::zeros(walk.frames[0].depth.size(), CV_16UC1);
  bool relocalised = false;
  TimestampNs t = 0;
  const auto add = [&](const cv::Mat& color, const cv::Mat& depth) {
    relocalised =
        mapper.AddKeyframe(t, color, depth).state == TrackingState::kRelocalised || relocalised;
    t += 1'000'000'000;
  };
  for (size_t i = 0; i < 30; ++i) add(walk.frames[i].color, walk.frames[i].depth);
  for (int i = 0; i < 4; ++i) add(black, no_depth);
  for (size_t i = 10; i < 25; ++i) add(walk.frames[i].color, walk.frames[i].depth);
  *gap_s = 5.0;  // from frame 29's keyframe to frame 10's
  *jump_m = (walk.frames[29].world_from_cam_gt->inverse() * *walk.frames[10].world_from_cam_gt)
                .translation()
                .norm();
  return {mapper.NumSegments(), relocalised};
}

TEST(Mapper, AJoinThatWouldMakeTheWalkJumpIsRefused) {
  // The same walk twice: with bounds the jump fits in, the segments are joined; with a speed
  // bound half the jump's, the relocalisation is refused and the segment stays apart (as a
  // look-alike room 10 m away would).
  double gap_s = 0.0;
  double jump_m = 0.0;
  MapperOptions options = SmallVocabulary();
  options.walk_slack_m = 0.0;
  options.walk_max_turn_rate_dps = 1000.0;
  options.walk_max_speed_mps = 10.0;
  const auto [loose_segments, loose_relocalised] = WalkBackAfterABlindGap(options, &gap_s, &jump_m);
  ASSERT_GT(jump_m, 0.3) << "the test needs the walk to come back from elsewhere";
  EXPECT_TRUE(loose_relocalised);
  // The blank keyframes are segments of their own: they are never joined.
  EXPECT_EQ(loose_segments, 1 + 4);

  options.walk_max_speed_mps = 0.5 * jump_m / gap_s;
  const auto [tight_segments, tight_relocalised] = WalkBackAfterABlindGap(options, &gap_s, &jump_m);
  EXPECT_FALSE(tight_relocalised);
  EXPECT_EQ(tight_segments, 1 + 4 + 1);
  std::printf("walked back %.2f m in %.0f s: joined under %.1f m/s, refused under %.2f m/s\n",
              jump_m, gap_s, 10.0, options.walk_max_speed_mps);
}

TEST(Mapper, OptionsRefuseAnImpossibleWalkBound) {
  std::string error;
  EXPECT_TRUE(MapperOptions().Check(&error)) << error;
  MapperOptions still;
  still.walk_max_speed_mps = 0.0;
  EXPECT_FALSE(still.Check(&error));
  EXPECT_NE(error.find("walk_max_speed_mps"), std::string::npos) << error;
  MapperOptions negative_gap;
  negative_gap.walk_max_gap_s = -1.0;
  EXPECT_FALSE(negative_gap.Check(&error));
  MapperOptions no_tilt;
  no_tilt.walk_max_tilt_deg = 0.0;
  EXPECT_FALSE(no_tilt.Check(&error));
  EXPECT_NE(error.find("walk_max_tilt_deg"), std::string::npos) << error;
  EXPECT_THROW(Mapper(HandheldWalkAt5Hz().camera, still), Error);
}

// A keyframe, then the same view upside down (the camera rolled half a turn where it stood):
// registration matches it, as it matched a row of locker doors read upside down at 1 Hz. Returns
// the second keyframe's report and the mapper's segments.
std::pair<KeyframeReport, int> AddAViewAndItUpsideDown(const MapperOptions& options) {
  const RgbdFrame& frame = HandheldWalkAt5Hz().frames[20];
  Mapper mapper(HandheldWalkAt5Hz().camera, options);
  mapper.AddKeyframe(0, frame.color, frame.depth);
  cv::Mat color;
  cv::Mat depth;
  cv::rotate(frame.color, color, cv::ROTATE_180);
  cv::rotate(frame.depth, depth, cv::ROTATE_180);
  KeyframeReport report = mapper.AddKeyframe(1'000'000'000, color, depth);
  return {report, mapper.NumSegments()};
}

TEST(Mapper, ARegistrationThatTurnsTheCameraUpsideDownIsRefused) {
  MapperOptions any_tilt = SmallVocabulary();
  any_tilt.walk_max_tilt_deg = 180.0;
  const auto [linked, linked_segments] = AddAViewAndItUpsideDown(any_tilt);
  ASSERT_EQ(linked_segments, 1) << "registration must match the view upside down: "
                                << linked.odometry_failure;
  // The registered roll is the half turn (the principal point sits half a pixel off centre).
  const Eigen::Isometry3d first_from_second = linked.world_from_cam;
  EXPECT_LT(first_from_second.linear().col(1).y(), -0.99);

  const auto [refused, refused_segments] = AddAViewAndItUpsideDown(SmallVocabulary());
  EXPECT_EQ(refused_segments, 2);
  EXPECT_NE(refused.odometry_failure.find("down axis"), std::string::npos)
      << refused.odometry_failure;
  std::printf("upside down: %s\n", refused.odometry_failure.c_str());
}

TEST(Mapper, AFalseLoopIsRejectedAndDoesNotBendTheMap) {
  const Walk& walk = HandheldWalkAt5Hz();
  std::vector<StampedPose> ground_truth;
  for (const RgbdFrame& frame : walk.frames) {
    ground_truth.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
  }
  Mapper mapper(walk.camera, SmallVocabulary());
  for (size_t i = 0; i < 45; ++i) {
    const RgbdFrame& frame = walk.frames[i];
    mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
  }
  const std::vector<StampedPose> before = mapper.Trajectory();
  MapperLink wrong;
  wrong.from = 2;
  wrong.to = 44;
  wrong.to_in_from = Eigen::Isometry3d::Identity();  // "44 is where 2 was": it is not
  wrong.information = mapper.Links().back().information;
  wrong.type = LinkType::kLoopClosure;
  const double apart = (ground_truth[2].world_from_cam.inverse() * ground_truth[44].world_from_cam)
                           .translation()
                           .norm();
  ASSERT_GT(apart, 0.5) << "the test needs two distant keyframes";
  const KeyframeReport report = mapper.AddExternalLink(wrong);
  EXPECT_EQ(report.links_rejected, 1);
  EXPECT_FALSE(mapper.Links().back().active);
  // The optimisation that rejected it also fused the redundant odometry links for the first time,
  // so poses move a little; the map must not get worse.
  const std::vector<StampedPose> truth(ground_truth.begin(), ground_truth.begin() + 45);
  const double ate_before = EvaluateTrajectory(truth, before).ate_rmse_m;
  const double ate_after = EvaluateTrajectory(truth, mapper.Trajectory()).ate_rmse_m;
  std::printf("false loop %.2f m off: ATE %.4f m before, %.4f m after\n", apart, ate_before,
              ate_after);
  EXPECT_LT(ate_after, 1.1 * ate_before + 0.002);
}

// While mapping, a loop is judged against the loops before it: a false loop the graph could
// still bend to, claiming more than the right loops that come after it, switches right loops off.
// The end's solve turns them back on and judges all of them together.
TEST(Mapper, TheEndJudgesTheLoopsSwitchedOffAgainAndTheRightOnesOutvoteAFalseOne) {
  const Walk& walk = HandheldWalkAt5Hz();
  std::vector<StampedPose> truth;
  for (size_t i = 0; i < 45; ++i) {
    truth.push_back({walk.frames[i].timestamp_ns, *walk.frames[i].world_from_cam_gt});
  }
  const auto true_link = [&truth](int64_t from, int64_t to) {
    return truth[static_cast<size_t>(from)].world_from_cam.inverse() *
           truth[static_cast<size_t>(to)].world_from_cam;
  };
  for (const int final_retry_max_loops : {100, 0}) {
    MapperOptions options = SmallVocabulary();
    options.final_retry_max_loops = final_retry_max_loops;
    // Odometry held by squares, not the Cauchy loss: with it 45 keyframes bend under the 5 cm
    // below and keep every loop, false or right; a long walk's graph cannot.
    options.pose_graph.odometry_loss_scale = 0.0;
    Mapper mapper(walk.camera, options);
    for (size_t i = 0; i < 45; ++i) {
      const RgbdFrame& frame = walk.frames[i];
      mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
    }
    const Eigen::Matrix<double, 6, 6> information = mapper.Links().back().information;
    MapperLink wrong;
    wrong.from = 2;
    wrong.to = 44;
    // Slid 5 cm along the camera's y (up a bookcase's shelves), claiming 4 times the information
    // of the right loops: a loop this small a graph of 45 keyframes still bends to.
    wrong.to_in_from = Eigen::Translation3d(0.0, 0.05, 0.0) * true_link(2, 44);
    wrong.information = 4.0 * information;
    wrong.type = LinkType::kLoopClosure;
    ASSERT_EQ(mapper.AddExternalLink(wrong).links_rejected, 0) << "the graph bends to it";
    const size_t wrong_index = mapper.Links().size() - 1;
    std::vector<size_t> right_indices;
    std::vector<size_t> switched_off;
    for (const auto& [from, to] : {std::pair<int64_t, int64_t>(3, 43), {4, 42}, {5, 41}}) {
      MapperLink right;
      right.from = from;
      right.to = to;
      right.to_in_from = true_link(from, to);
      right.information = information;
      right.type = LinkType::kLoopClosure;
      mapper.AddExternalLink(right);
      right_indices.push_back(mapper.Links().size() - 1);
      if (!mapper.Links().back().active) switched_off.push_back(right_indices.back());
    }
    ASSERT_TRUE(mapper.Links()[wrong_index].active);
    ASSERT_GE(switched_off.size(), 2u) << "the false loop, first, switches right ones off";
    const double ate_before = EvaluateTrajectory(truth, mapper.Trajectory()).ate_rmse_m;

    const KeyframeReport report = mapper.OptimiseWhole();
    const double ate_after = EvaluateTrajectory(truth, mapper.Trajectory()).ate_rmse_m;
    std::printf("retry up to %d loops: ATE %.4f m before the end's solve, %.4f m after\n",
                final_retry_max_loops, ate_before, ate_after);
    if (final_retry_max_loops == 0) {
      EXPECT_TRUE(report.reactivated_links.empty());
      EXPECT_TRUE(mapper.Links()[wrong_index].active);
      for (size_t index : switched_off) EXPECT_FALSE(mapper.Links()[index].active) << index;
      continue;
    }
    EXPECT_FALSE(mapper.Links()[wrong_index].active);
    for (size_t index : right_indices) EXPECT_TRUE(mapper.Links()[index].active) << index;
    // The report says what changed: the right loops that were off are back on, the false one off.
    EXPECT_EQ(report.reactivated_links, switched_off);
    EXPECT_EQ(report.rejected_links, std::vector<size_t>{wrong_index});
    EXPECT_EQ(report.links_rejected, 1);
    EXPECT_LT(ate_after, ate_before);
  }
}

TEST(Mapper, AResumedSessionRelocalisesIntoTheRestoredMap) {
  // Day one maps frames 0-29; day two restores that map (as `sightmap map` does from the model)
  // and walks frames 15-29 again: its first keyframe cannot be registered by odometry, is
  // relocalised, and the new keyframes share the stored map's frame.
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper first(walk.camera, SmallVocabulary());
  for (size_t i = 0; i < 30; ++i) {
    first.AddKeyframe(walk.frames[i].timestamp_ns, walk.frames[i].color, walk.frames[i].depth);
  }
  ASSERT_NE(first.vocabulary(), nullptr);
  Mapper second(walk.camera, SmallVocabulary());
  second.SetVocabulary(first.vocabulary());
  for (size_t i = 0; i < 30; ++i) {
    const int64_t id = second.RestoreKeyframe(
        walk.frames[i].timestamp_ns, first.FeaturesOf(static_cast<int64_t>(i)),
        walk.frames[i].depth, first.WorldFromCam(static_cast<int64_t>(i)));
    EXPECT_EQ(id, static_cast<int64_t>(i));
  }
  for (const MapperLink& link : first.Links()) second.RestoreLink(link);
  EXPECT_EQ(second.NumSegments(), first.NumSegments());
  std::vector<TrackingState> states;
  for (size_t i = 15; i < 30; ++i) {
    const RgbdFrame& frame = walk.frames[i];
    const KeyframeReport report =
        second.AddKeyframe(frame.timestamp_ns + 1'000'000'000'000, frame.color, frame.depth);
    states.push_back(report.state);
  }
  // The first keyframe finds its place; the second confirms it (a join waits for two to agree).
  EXPECT_EQ(states[1], TrackingState::kRelocalised)
      << "the same views as stored keyframes must relocalise at once";
  EXPECT_EQ(second.NumSegments(), 1);
  // The revisit lands where day one put the same frames.
  for (size_t i = 15; i < 30; ++i) {
    const int64_t again = static_cast<int64_t>(30 + i - 15);
    const double apart = (second.WorldFromCam(again).translation() -
                          second.WorldFromCam(static_cast<int64_t>(i)).translation())
                             .norm();
    EXPECT_LT(apart, 0.05) << "frame " << i;
  }
}

TEST(Mapper, KeyframesAtKnownPosesKeepThemAndAreIndexed) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, SmallVocabulary());
  for (const RgbdFrame& frame : walk.frames) {
    const KeyframeReport report = mapper.AddKeyframeAtPose(frame.timestamp_ns, frame.color,
                                                           frame.depth, *frame.world_from_cam_gt);
    EXPECT_EQ(report.state, TrackingState::kTracking);
    EXPECT_FALSE(report.loop_closed);
  }
  ASSERT_EQ(mapper.NumKeyframes(), walk.frames.size());
  EXPECT_EQ(mapper.NumSegments(), 1);
  ASSERT_NE(mapper.vocabulary(), nullptr);  // trained after 15 keyframes, as when mapping
  for (size_t i = 0; i < walk.frames.size(); ++i) {
    const Eigen::Isometry3d error =
        walk.frames[i].world_from_cam_gt->inverse() * mapper.WorldFromCam(static_cast<int64_t>(i));
    EXPECT_LT(error.translation().norm(), 1e-6) << "keyframe " << i;
    EXPECT_LT(RotationAngleDeg(error), 1e-4) << "keyframe " << i;
  }
}

TEST(Mapper, TheFirstKeyframeSitsAtTheGivenPose) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera, SmallVocabulary());
  const Eigen::Isometry3d& anchor = *walk.frames[0].world_from_cam_gt;
  mapper.SetFirstPose(anchor);
  for (size_t i = 0; i < 3; ++i) {
    mapper.AddKeyframe(walk.frames[i].timestamp_ns, walk.frames[i].color, walk.frames[i].depth);
  }
  EXPECT_LT((mapper.WorldFromCam(0).translation() - anchor.translation()).norm(), 1e-9);
  // Later keyframes are registered in that frame: near their true poses.
  EXPECT_LT((mapper.WorldFromCam(2).translation() - walk.frames[2].world_from_cam_gt->translation())
                .norm(),
            0.02);
  EXPECT_THROW(mapper.SetFirstPose(anchor), Error);
}

TEST(Mapper, RefusesImagesThatDoNotFitTheCamera) {
  const Walk& walk = HandheldWalkAt5Hz();
  Mapper mapper(walk.camera);
  const cv::Mat small(240, 320, CV_8UC3, cv::Scalar(0, 0, 0));
  const cv::Mat small_depth(240, 320, CV_16UC1, cv::Scalar(0));
  EXPECT_THROW(mapper.AddKeyframe(0, small, small_depth), Error);
  EXPECT_THROW(mapper.AddKeyframe(0, walk.frames[0].color, small_depth), Error);
  EXPECT_EQ(mapper.NumKeyframes(), 0u);
  MapperOptions bad;
  bad.odometry_window = 0;
  EXPECT_THROW(Mapper(walk.camera, bad), InvalidArgument);
}

}  // namespace
}  // namespace sightmap::slam
