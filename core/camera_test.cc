#include "core/camera.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap {
namespace {

// The longer side brought to the limit, the aspect kept, no side below a pixel; a size within it
// (or no limit) unchanged.
TEST(SizeAtMostOfSide, ScalesTheLongerSideDownToTheLimit) {
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(1280, 960), 640), cv::Size(640, 480));
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(960, 1280), 640), cv::Size(480, 640));
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(1001, 333), 100), cv::Size(100, 33));
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(20000, 1), 640), cv::Size(640, 1));
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(640, 480), 640), cv::Size(640, 480));
  EXPECT_EQ(SizeAtMostOfSide(cv::Size(640, 480), 0), cv::Size(640, 480));
}

TEST(Intrinsics, FromFieldOfViewMatchesPinholeFormula) {
  const Intrinsics k = Intrinsics::FromFieldOfView(640, 480, 1.0145, 0.7898);
  EXPECT_NEAR(k.fx, 640.0 / (2.0 * std::tan(1.0145 / 2.0)), 1e-9);
  EXPECT_NEAR(k.fy, 480.0 / (2.0 * std::tan(0.7898 / 2.0)), 1e-9);
  EXPECT_DOUBLE_EQ(k.cx, 319.5);
  EXPECT_DOUBLE_EQ(k.cy, 239.5);
  EXPECT_NEAR(k.HorizontalFieldOfView(), 1.0145, 1e-12);
}

TEST(Intrinsics, ZeroVerticalFovMeansSquarePixels) {
  const Intrinsics k = Intrinsics::FromFieldOfView(320, 240, 1.0, 0.0);
  EXPECT_DOUBLE_EQ(k.fx, k.fy);
}

TEST(Intrinsics, RejectsImpossibleFieldOfView) {
  EXPECT_THROW(Intrinsics::FromFieldOfView(640, 480, 0.0, 0.0), InvalidArgument);
  EXPECT_THROW(Intrinsics::FromFieldOfView(0, 480, 1.0, 0.0), InvalidArgument);
  EXPECT_THROW(Intrinsics::FromFieldOfView(640, 480, 4.0, 0.0), InvalidArgument);
}

TEST(Intrinsics, ScaledKeepsTheSameRays) {
  const Intrinsics small = Intrinsics::FromFieldOfView(320, 240, 1.02, 0.79);
  const Intrinsics big = small.Scaled(640, 480);
  // The ray through the small image's pixel (u, v) goes through the big image's (2u + 0.5, 2v +
  // 0.5).
  const Eigen::Vector3d ray_small = small.Unproject(100.0, 50.0, 1.0);
  const Eigen::Vector3d ray_big = big.Unproject(200.5, 100.5, 1.0);
  EXPECT_NEAR((ray_small - ray_big).norm(), 0.0, 1e-12);
  EXPECT_NEAR(big.HorizontalFieldOfView(), small.HorizontalFieldOfView(), 1e-12);
}

TEST(Intrinsics, ProjectInvertsUnproject) {
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = 525.0;
  k.fy = 520.0;
  k.cx = 319.5;
  k.cy = 239.5;
  const Eigen::Vector3d p = k.Unproject(12.25, 400.75, 2.5);
  const Eigen::Vector2d uv = k.Project(p);
  EXPECT_NEAR(uv.x(), 12.25, 1e-9);
  EXPECT_NEAR(uv.y(), 400.75, 1e-9);
  EXPECT_NEAR(k.MirroredHorizontally().cx, 319.5, 1e-12);
}

TEST(Intrinsics, FromPinholeKeepsEachValueInItsPlace) {
  const Intrinsics k = Intrinsics::FromPinhole(640, 480, 525.0, 520.0, 319.5, 239.0);
  EXPECT_EQ(k.width, 640);
  EXPECT_EQ(k.height, 480);
  EXPECT_EQ(k.fx, 525.0);
  EXPECT_EQ(k.fy, 520.0);
  EXPECT_EQ(k.cx, 319.5);
  EXPECT_EQ(k.cy, 239.0);
  const Eigen::Vector2d pixel = k.Project(Eigen::Vector3d(0.1, -0.2, 2.0));
  EXPECT_NEAR(pixel.x(), 319.5 + 525.0 * 0.05, 1e-12);
  EXPECT_NEAR(pixel.y(), 239.0 - 520.0 * 0.1, 1e-12);
}

TEST(Intrinsics, CheckRejectsNonPositiveFocalLength) {
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  std::string error;
  EXPECT_FALSE(k.Check(&error));
  EXPECT_FALSE(error.empty());
  k.fx = k.fy = 500.0;
  EXPECT_TRUE(k.Check(&error));
}

TEST(Intrinsics, CheckRejectsAbsurdValues) {
  const Intrinsics good = Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
  std::string error;
  ASSERT_TRUE(good.Check(&error)) << error;
  auto with = [&](auto change) {
    Intrinsics k = good;
    change(k);
    return k;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(with([](Intrinsics& k) { k.fx = 1e300; }).Check(&error));
  EXPECT_NE(error.find("at most 100 x"), std::string::npos) << error;
  EXPECT_FALSE(with([&](Intrinsics& k) { k.fy = nan; }).Check(&error));
  EXPECT_FALSE(with([](Intrinsics& k) { k.cx = 1e300; }).Check(&error));
  EXPECT_FALSE(with([&](Intrinsics& k) { k.cy = nan; }).Check(&error));
  EXPECT_FALSE(with([](Intrinsics& k) { k.width = 1000000; }).Check(&error));
  // Long lenses and off-centre principal points within reason stay valid.
  EXPECT_TRUE(with([](Intrinsics& k) { k.fx = k.fy = 60000.0; }).Check(&error)) << error;
  EXPECT_TRUE(with([](Intrinsics& k) { k.cx = -100.0; }).Check(&error)) << error;
}

TEST(LookAt, LooksAtTheTargetWithImageRowsDownTheWorld) {
  const Eigen::Vector3d eye(1.0, 2.0, 1.5);
  const Eigen::Vector3d target(4.0, -1.0, 2.5);
  const Eigen::Isometry3d world_from_cam = LookAt(eye, target, Eigen::Vector3d::UnitZ());
  const Eigen::Matrix3d r = world_from_cam.linear();
  EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  const Eigen::Vector3d in_cam = world_from_cam.inverse() * target;
  EXPECT_NEAR(in_cam.x(), 0.0, 1e-12);
  EXPECT_NEAR(in_cam.y(), 0.0, 1e-12);
  EXPECT_NEAR(in_cam.z(), (target - eye).norm(), 1e-12);
  EXPECT_NEAR(r.col(0).z(), 0.0, 1e-12);  // level: no roll
  EXPECT_LT(r.col(1).z(), 0.0);           // image down is world down
  EXPECT_THROW(LookAt(eye, eye + Eigen::Vector3d(0, 0, 2), Eigen::Vector3d::UnitZ()), Error);
}

}  // namespace
}  // namespace sightmap
