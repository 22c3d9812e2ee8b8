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

TEST(BridgeBlindRun, DurationsMustBePositive) {
  const TimedMotion step{WalkStep(0.0, 1.0), 1.0};
  EXPECT_THROW(BridgeBlindRun(step, {0.0}, step), InvalidArgument);
  EXPECT_THROW(BridgeBlindRun(TimedMotion{}, {1.0}, step), InvalidArgument);
  EXPECT_TRUE(BridgeBlindRun(step, {}, step).empty());
}

}  // namespace
}  // namespace sightmap::slam
