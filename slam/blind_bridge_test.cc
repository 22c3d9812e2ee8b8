#include "slam/blind_bridge.h"

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::slam {
namespace {

// A step of a walker going 0.5 m/s forward while turning at `turn_dps`, over dt_s.
Eigen::Isometry3d WalkStep(double turn_dps, double dt_s) {
  Eigen::Matrix<double, 6, 1> velocity;
  velocity << 0.0, 0.0, 0.5, 0.0, DegToRad(turn_dps), 0.0;
  return ExpSe3(velocity * dt_s);
}

double TranslationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

TEST(BridgeBlindRun, AWalkerKeepingItsPaceIsBridgedByThatPace) {
  const TimedMotion step{WalkStep(20.0, 1.0), 1.0};
  const std::vector<Eigen::Isometry3d> bridged = BridgeBlindRun(step, {1.0, 1.0}, step);
  ASSERT_EQ(bridged.size(), 2u);
  for (const Eigen::Isometry3d& motion : bridged) {
    EXPECT_LT(TranslationError(motion, step.previous_from_cam), 1e-9);
    EXPECT_LT(RotationAngleDeg(motion.rotation(), step.previous_from_cam.rotation()), 1e-9);
  }
}

TEST(BridgeBlindRun, AOneSecondGapBetweenStraightAndTurningTurnsHalfAsFast) {
  // Walking straight before, turning 35 deg/s after: the second between is the turn's start.
  const TimedMotion before{WalkStep(0.0, 1.0), 1.0};
  const TimedMotion after{WalkStep(35.0, 1.0), 1.0};
  const std::vector<Eigen::Isometry3d> bridged = BridgeBlindRun(before, {1.0}, after);
  ASSERT_EQ(bridged.size(), 1u);
  EXPECT_NEAR(RotationAngleDeg(bridged[0]), 17.5, 1e-9);
  EXPECT_NEAR(bridged[0].translation().z(), 0.5, 1e-9);
}

TEST(BridgeBlindRun, StepsLieOnTheLineByTheirTimes) {
  // Before: 0.5 s of walking straight; after: 0.1 s at 30 deg/s; blind: 1.0 s then 0.4 s. From
  // the middle of the motion before, the blind steps' middles lie 0.75 s and 1.45 s on, the
  // middle of the motion after 1.7 s on.
  const TimedMotion before{WalkStep(0.0, 0.5), 0.5};
  const TimedMotion after{WalkStep(30.0, 0.1), 0.1};
  const std::vector<Eigen::Isometry3d> bridged = BridgeBlindRun(before, {1.0, 0.4}, after);
  ASSERT_EQ(bridged.size(), 2u);
  EXPECT_NEAR(RotationAngleDeg(bridged[0]), 30.0 * (0.75 / 1.7) * 1.0, 1e-9);
  EXPECT_NEAR(RotationAngleDeg(bridged[1]), 30.0 * (1.45 / 1.7) * 0.4, 1e-9);
  EXPECT_NEAR(bridged[0].translation().z(), 0.5, 1e-9);
  EXPECT_NEAR(bridged[1].translation().z(), 0.2, 1e-9);
}

// A hand-held walker going on at 0.5 m/s while turning the camera at 35 deg/s about its down
// axis: the camera's pose at time t, in the world where it started.
Eigen::Isometry3d HeadTurningWalker(double t_s) {
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear() =
      Eigen::AngleAxisd(DegToRad(35.0 * t_s), Eigen::Vector3d::UnitY()).matrix();
  world_from_cam.translation() = Eigen::Vector3d(0.0, 0.0, 0.5 * t_s);
  return world_from_cam;
}

Eigen::Isometry3d HeadTurningStep(double from_s, double to_s) {
  return HeadTurningWalker(from_s).inverse() * HeadTurningWalker(to_s);
}

TEST(BridgeBlindRun, AWalkerLookingAboutKeepsItsVelocityInTheWorld) {
  // Measured from -1 to 0 s and from 2 to 3 s, blind from 0 to 2 s.
  const TimedMotion before{HeadTurningStep(-1.0, 0.0), 1.0};
  const TimedMotion after{HeadTurningStep(2.0, 3.0), 1.0};
  const std::vector<Eigen::Isometry3d> world =
      BridgeBlindRun(before, {1.0, 1.0}, after, BridgeFrame::kWorld);
  const std::vector<Eigen::Isometry3d> camera =
      BridgeBlindRun(before, {1.0, 1.0}, after, BridgeFrame::kCamera);
  ASSERT_EQ(world.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Isometry3d truth = HeadTurningStep(k, k + 1.0);
    EXPECT_LT(TranslationError(world[k], truth), 1e-9) << "step " << k;
    EXPECT_LT(RotationAngleDeg(world[k].rotation(), truth.rotation()), 1e-9);
    // Keeping the velocity in the camera turns it with the head: 0.17 m off in each second.
    EXPECT_GT(TranslationError(camera[k], truth), 0.15) << "step " << k;
  }
}

TEST(BridgeBlindRun, AMeasuredTurnReplacesTheInterpolatedOne) {
  // The motions on both sides say the camera does not turn; the first blind step's ends show
  // it turned 35 degrees. That step takes the turn; so the motion after the run, measured in the
  // turned camera, goes 35 degrees off the one before, and the steps' velocities lie between
  // the two (a third and two thirds of the way), each in the camera where its step starts.
  const TimedMotion before{WalkStep(0.0, 1.0), 1.0};
  const TimedMotion after = before;
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(DegToRad(35.0), Eigen::Vector3d::UnitY()).matrix();
  const std::vector<Eigen::Isometry3d> bridged =
      BridgeBlindRun(before, {1.0, 1.0}, after, BridgeFrame::kWorld, {turn, std::nullopt});
  ASSERT_EQ(bridged.size(), 2u);
  EXPECT_LT(RotationAngleDeg(bridged[0].rotation(), turn), 1e-9);
  EXPECT_LT(RotationAngleDeg(bridged[1]), 1e-9);
  const Eigen::Vector3d forward(0.0, 0.0, 0.5);
  EXPECT_LT((bridged[0].translation() - (2.0 * forward + turn * forward) / 3.0).norm(), 1e-9);
  EXPECT_LT(
      (bridged[1].translation() - turn.transpose() * (forward + 2.0 * turn * forward) / 3.0).norm(),
      1e-9);
  EXPECT_THROW(BridgeBlindRun(before, {1.0, 1.0}, after, BridgeFrame::kWorld, {turn}),
               InvalidArgument);
}

TEST(BridgeBlindRun, DurationsMustBePositive) {
  const TimedMotion step{WalkStep(0.0, 1.0), 1.0};
  EXPECT_THROW(BridgeBlindRun(step, {0.0}, step), InvalidArgument);
  EXPECT_THROW(BridgeBlindRun(TimedMotion{}, {1.0}, step), InvalidArgument);
  EXPECT_TRUE(BridgeBlindRun(step, {}, step).empty());
}

}  // namespace
}  // namespace sightmap::slam
