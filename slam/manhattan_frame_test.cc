#include "slam/manhattan_frame.h"

#include <cmath>
#include <limits>
#include <set>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rotation.h"
#include "slam/planes_testing.h"

namespace sightmap::slam {
namespace {

using testing::kPlaneCamera;
using testing::RenderPlanes;
using testing::WorldFromCam;
constexpr const Intrinsics& kCamera = kPlaneCamera;

// The rotation error of a fit against the truth, over the namings of the axes [deg].
double FitErrorDeg(const ManhattanFit& fit, const Eigen::Matrix3d& world_from_cam) {
  return RadToDeg(
      NearestManhattanRotation(Eigen::Matrix3d::Identity(), fit.cam_from_manhattan, world_from_cam)
          .second);
}

TEST(ManhattanFrame, TheTwentyFourNamingsOfTheAxesAreDistinctRotations) {
  const std::vector<Eigen::Matrix3d>& symmetries = ManhattanSymmetries();
  ASSERT_EQ(symmetries.size(), 24u);
  std::set<std::vector<int>> distinct;
  for (const Eigen::Matrix3d& symmetry : symmetries) {
    EXPECT_NEAR(symmetry.determinant(), 1.0, 1e-12);
    EXPECT_TRUE((symmetry * symmetry.transpose()).isIdentity(1e-12));
    std::vector<int> entries;
    for (int i = 0; i < 9; ++i) entries.push_back(static_cast<int>(symmetry.data()[i]));
    distinct.insert(entries);
  }
  EXPECT_EQ(distinct.size(), 24u);
}

// A room corner (floor, two walls 2.5 and 2 m away) seen from a camera turned 27 degrees off the
// walls and tilted 15 degrees down: the axes come out within a tenth of a degree, whichever
// naming of them the fit picked.
TEST(ManhattanFrame, ARoomCornerGivesTheCamerasRotation) {
  const std::vector<std::pair<Eigen::Vector3d, double>> corner = {{Eigen::Vector3d::UnitZ(), 0.0},
                                                                  {Eigen::Vector3d::UnitX(), 2.5},
                                                                  {Eigen::Vector3d::UnitY(), 2.0}};
  for (const double yaw_deg : {27.0, 63.0, 40.0}) {
    const Eigen::Matrix3d world_from_cam = WorldFromCam(yaw_deg, 15.0);
    const std::optional<ManhattanFit> fit =
        FitManhattanFrame(RenderPlanes(world_from_cam, corner), kCamera, ManhattanOptions());
    ASSERT_TRUE(fit.has_value()) << yaw_deg;
    EXPECT_LT(FitErrorDeg(*fit, world_from_cam), 0.1) << yaw_deg;
    EXPECT_GT(fit->normals, 1000);
  }
}

// Where the world holds the axes and which naming the camera's fit used do not matter: the
// candidate nearest an estimate 20 degrees off is the true rotation.
TEST(ManhattanFrame, TheNearestNamingOfTheAxesIsTheTruth) {
  const Eigen::Matrix3d world_from_axes =
      Eigen::AngleAxisd(DegToRad(33.0), Eigen::Vector3d::UnitZ()).matrix();
  const Eigen::Matrix3d world_from_cam = WorldFromCam(-71.0, 8.0);
  const Eigen::Matrix3d renamed = ManhattanSymmetries()[7];
  const Eigen::Matrix3d cam_from_axes = world_from_cam.transpose() * world_from_axes * renamed;
  const Eigen::Matrix3d estimate =
      Eigen::AngleAxisd(DegToRad(20.0), Eigen::Vector3d::UnitZ()).matrix() * world_from_cam;
  const auto [measured, deviation] =
      NearestManhattanRotation(world_from_axes, cam_from_axes, estimate);
  EXPECT_TRUE(measured.isApprox(world_from_cam, 1e-9));
  EXPECT_NEAR(RadToDeg(deviation), 20.0, 1e-6);
}

// One axis is not a rotation: a bare wall straight ahead, or the floor alone, gives no fit; nor
// does a frame without depth.
TEST(ManhattanFrame, OneAxisOrNoDepthGivesNoFit) {
  const Eigen::Matrix3d level = WorldFromCam(0.0, 0.0);
  EXPECT_FALSE(FitManhattanFrame(RenderPlanes(level, {{Eigen::Vector3d::UnitX(), 2.0}}), kCamera,
                                 ManhattanOptions())
                   .has_value());
  const Eigen::Matrix3d down = WorldFromCam(0.0, 60.0);
  EXPECT_FALSE(FitManhattanFrame(RenderPlanes(down, {{Eigen::Vector3d::UnitZ(), 0.0}}), kCamera,
                                 ManhattanOptions())
                   .has_value());
  const cv::Mat empty(kCamera.height, kCamera.width, CV_16UC1, cv::Scalar(0));
  EXPECT_FALSE(FitManhattanFrame(empty, kCamera, ManhattanOptions()).has_value());
  EXPECT_THROW(
      FitManhattanFrame(cv::Mat(10, 10, CV_16UC1, cv::Scalar(0)), kCamera, ManhattanOptions()),
      Error);
  ManhattanOptions bad;
  bad.assign_deg = 50.0;
  EXPECT_THROW(FitManhattanFrame(empty, kCamera, bad), Error);
}

}  // namespace
}  // namespace sightmap::slam
