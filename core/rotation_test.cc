#include "core/rotation.h"

#include <cmath>

#include <gtest/gtest.h>

namespace sightmap {
namespace {

TEST(RotationAngleDeg, MeasuresTheTurnWhateverTheAxis) {
  EXPECT_NEAR(RotationAngleDeg(Eigen::Matrix3d::Identity()), 0.0, 1e-12);
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, -2.0, 0.5).normalized();
  for (double deg : {0.5, 30.0, 90.0, 179.0}) {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(DegToRad(deg), axis).toRotationMatrix();
    EXPECT_NEAR(RotationAngleDeg(r), deg, 1e-9);
    EXPECT_NEAR(RotationAngleDeg(Eigen::Matrix3d(r.transpose())), deg, 1e-9);  // either way
  }
  // Between two orientations: 40 deg about z, then 70 deg about z.
  const Eigen::Matrix3d a =
      Eigen::AngleAxisd(DegToRad(40.0), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d b =
      Eigen::AngleAxisd(DegToRad(70.0), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_NEAR(RotationAngleDeg(a, b), 30.0, 1e-9);
  EXPECT_NEAR(RotationAngleDeg(b, a), 30.0, 1e-9);
  // A motion's translation does not count.
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() = b;
  motion.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  EXPECT_NEAR(RotationAngleDeg(motion), 70.0, 1e-9);
}

TEST(MotionWithin, BoundsTheMoveAndTheTurnBothInclusive) {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() = Eigen::AngleAxisd(DegToRad(10.0), Eigen::Vector3d::UnitY()).toRotationMatrix();
  motion.translation() = Eigen::Vector3d(0.3, 0.0, 0.4);  // 0.5 m
  EXPECT_TRUE(MotionWithin(motion, 0.5, 10.0 + 1e-9));
  EXPECT_TRUE(MotionWithin(motion, 1.0, 20.0));
  EXPECT_FALSE(MotionWithin(motion, 0.49, 20.0));
  EXPECT_FALSE(MotionWithin(motion, 1.0, 9.9));
  motion.translation().x() = std::nan("");
  EXPECT_FALSE(MotionWithin(motion, 1e9, 180.0));
}

TEST(Skew, IsTheCrossProduct) {
  const Eigen::Vector3d v(0.3, -1.2, 2.0);
  const Eigen::Vector3d w(-0.7, 0.4, 1.1);
  EXPECT_LT((Skew(v) * w - v.cross(w)).norm(), 1e-15);
  EXPECT_LT((Skew(v) + Skew(v).transpose()).norm(), 1e-15);
}

// ExpSe3 is [R(w) | t], not the screw exponential: the translation is t whatever the turn.
TEST(ExpSe3, IsTheTranslationAndTheRotationVectorAndLogSe3UndoesIt) {
  Eigen::Matrix<double, 6, 1> delta;
  delta << 0.3, -0.2, 0.1, 0.0, 0.0, 0.5 * M_PI;
  const Eigen::Isometry3d motion = ExpSe3(delta);
  EXPECT_TRUE(motion.translation().isApprox(Eigen::Vector3d(0.3, -0.2, 0.1)));
  EXPECT_TRUE((motion.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(LogSe3(motion).isApprox(delta, 1e-12));
  EXPECT_TRUE(ExpSe3(Eigen::Matrix<double, 6, 1>::Zero()).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_LT(LogSe3(Eigen::Isometry3d::Identity()).norm(), 1e-15);
}

// Bearings run from e1 towards e2 in [0, 360); the height along up plays no part.
// T Exp(r) T^-1 = Exp(Ad r) to first order in a small error r.
TEST(AdjointSe3, CarriesAnErrorIntoTheOtherFrame) {
  const Eigen::Isometry3d motion =
      ExpSe3((Eigen::Matrix<double, 6, 1>() << 1.0, -2.0, 0.5, 0.3, -0.4, 0.9).finished());
  const Eigen::Matrix<double, 6, 1> error =
      (Eigen::Matrix<double, 6, 1>() << 1e-5, 2e-5, -1e-5, 2e-5, -1e-5, 3e-5).finished();
  const Eigen::Isometry3d carried = motion * ExpSe3(error) * motion.inverse();
  const Eigen::Matrix<double, 6, 1> expected = AdjointSe3(motion) * error;
  EXPECT_LT((LogSe3(carried) - expected).norm(), 1e-3 * error.norm());  // second order
}

TEST(FloorBearingDeg, FromTheFirstAxisTowardsTheSecond) {
  Eigen::Vector3d e1, e2;
  FloorAxes(Eigen::Vector3d::UnitZ(), &e1, &e2);
  EXPECT_NEAR(FloorBearingDeg(Eigen::Vector3d(2, 0, 5), e1, e2), 0.0, 1e-12);
  EXPECT_NEAR(FloorBearingDeg(Eigen::Vector3d(0, 1, -3), e1, e2), 90.0, 1e-12);
  EXPECT_NEAR(FloorBearingDeg(Eigen::Vector3d(-1, -1, 0), e1, e2), 225.0, 1e-12);
  EXPECT_NEAR(FloorBearingDeg(Eigen::Vector3d(1, -1e-9, 0), e1, e2), 360.0, 1e-6);
}

TEST(FloorAxes, WorldXOnTheFloorOrWorldYWhenXIsUp) {
  Eigen::Vector3d e1, e2;
  FloorAxes(Eigen::Vector3d::UnitZ(), &e1, &e2);
  EXPECT_TRUE(e1.isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(e2.isApprox(Eigen::Vector3d::UnitY()));
  // A map anchored at a camera frame: up is -y.
  FloorAxes(-Eigen::Vector3d::UnitY(), &e1, &e2);
  EXPECT_TRUE(e1.isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(e2.isApprox(Eigen::Vector3d::UnitZ()));
  FloorAxes(Eigen::Vector3d::UnitX(), &e1, &e2);
  EXPECT_TRUE(e1.isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(e2.isApprox(Eigen::Vector3d::UnitZ()));
  // A tilted up: both axes unit, on the floor and at right angles.
  const Eigen::Vector3d up = Eigen::Vector3d(0.3, -0.2, 0.9).normalized();
  FloorAxes(up, &e1, &e2);
  EXPECT_NEAR(e1.norm(), 1.0, 1e-12);
  EXPECT_NEAR(e2.norm(), 1.0, 1e-12);
  EXPECT_NEAR(e1.dot(up), 0.0, 1e-12);
  EXPECT_NEAR(e2.dot(up), 0.0, 1e-12);
  EXPECT_NEAR(e1.dot(e2), 0.0, 1e-12);
  EXPECT_GT(e1.x(), 0.0);
}

}  // namespace
}  // namespace sightmap
