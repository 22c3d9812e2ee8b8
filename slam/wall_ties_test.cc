#include "slam/wall_ties.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rotation.h"
#include "slam/planes_testing.h"

namespace sightmap::slam {
namespace {

using testing::kPlaneCamera;
using testing::RenderPlanes;
using testing::WorldFromCam;

// A room corner: the floor (z = 0) and walls at x = 2.2 and y = 2.
const std::vector<std::pair<Eigen::Vector3d, double>> kCorner = {{Eigen::Vector3d::UnitZ(), 0.0},
                                                                 {Eigen::Vector3d::UnitX(), 2.2},
                                                                 {Eigen::Vector3d::UnitY(), 2.0}};

// A tie's error at the poses `world_from_from` and `world_from_to` [m].
double TieError(const PlaneTie& tie, const Eigen::Isometry3d& world_from_from,
                const Eigen::Isometry3d& world_from_to) {
  const Eigen::Vector3d to_in_from = world_from_from.inverse() * world_from_to.translation();
  return tie.normal_in_from.dot(to_in_from) - tie.offset_m;
}

// The planes a camera at `position` looking along `yaw_deg` (25 degrees down) sees of the corner.
PlaneSightings SeeCorner(int64_t id, int part, const Eigen::Vector3d& position, double yaw_deg) {
  PlaneSightings sightings;
  sightings.id = id;
  sightings.part = part;
  sightings.world_from_cam.linear() = WorldFromCam(yaw_deg, 25.0);
  sightings.world_from_cam.translation() = position;
  // The camera's view of the building's axes: the world's, up to naming.
  const Eigen::Matrix3d cam_from_axes = sightings.world_from_cam.linear().transpose();
  const std::vector<PlanePatch> patches =
      PlanePatches(RenderPlanes(sightings.world_from_cam.linear(), kCorner, position), kPlaneCamera,
                   ManhattanOptions());
  sightings.planes = FindAxisPlanes(patches, cam_from_axes, WallTieOptions());
  return sightings;
}

TEST(WallTies, TheWallsAndFloorADepthImageShowsAreFound) {
  const PlaneSightings seen = SeeCorner(0, 0, Eigen::Vector3d(0.0, 0.0, 1.5), 45.0);
  ASSERT_EQ(seen.planes.size(), 3u);
  // Each plane at its distance from the camera, its normal facing it.
  for (const auto& [normal_world, offset] : kCorner) {
    // From the plane towards the camera.
    const double distance = normal_world.dot(seen.world_from_cam.translation()) - offset;
    const Eigen::Vector3d facing = distance > 0.0 ? normal_world : (-normal_world).eval();
    int found = 0;
    for (const AxisPlane& plane : seen.planes) {
      if ((seen.world_from_cam.linear() * plane.normal_cam - facing).norm() > 1e-6) continue;
      ++found;
      EXPECT_NEAR(plane.offset_m, -std::abs(distance), 0.01) << normal_world.transpose();
      EXPECT_GE(plane.support, WallTieOptions().min_support);
      EXPECT_NEAR(plane.normal_cam.dot(plane.centroid_cam), plane.offset_m, 0.01);
    }
    EXPECT_EQ(found, 1) << normal_world.transpose();
  }
}

TEST(WallTies, PartsSeeingOneWallAreTiedAlongItsNormal) {
  // Two parts of two keyframes each; the map has the second part 0.15 m off along x.
  const Eigen::Vector3d shift(0.15, 0.0, 0.0);
  std::vector<PlaneSightings> truth = {SeeCorner(0, 0, Eigen::Vector3d(0.0, 0.0, 1.5), 30.0),
                                       SeeCorner(1, 0, Eigen::Vector3d(0.2, -0.3, 1.5), 40.0),
                                       SeeCorner(2, 1, Eigen::Vector3d(0.8, 0.4, 1.5), 20.0),
                                       SeeCorner(3, 1, Eigen::Vector3d(1.0, 0.1, 1.5), 35.0)};
  std::vector<PlaneSightings> mapped = truth;
  for (PlaneSightings& keyframe : mapped) {
    if (keyframe.part == 1) keyframe.world_from_cam.translation() += shift;
  }
  const std::vector<PlaneTie> ties =
      TieWalls(mapped, Eigen::Matrix3d::Identity(), WallTieOptions());
  ASSERT_FALSE(ties.empty());
  int along_shift = 0;
  for (const PlaneTie& tie : ties) {
    EXPECT_NE(mapped[tie.from].part, mapped[tie.to].part);
    // Right at the true poses; the mapped ones are off by the shift along the tie's normal.
    EXPECT_NEAR(TieError(tie, truth[tie.from].world_from_cam, truth[tie.to].world_from_cam), 0.0,
                0.01);
    const Eigen::Vector3d normal_world =
        truth[tie.from].world_from_cam.linear() * tie.normal_in_from;
    const double moved = normal_world.dot(mapped[tie.from].part == 1 ? -shift : shift);
    EXPECT_NEAR(TieError(tie, mapped[tie.from].world_from_cam, mapped[tie.to].world_from_cam),
                moved, 0.01);
    if (std::abs(moved) > 0.1) ++along_shift;
  }
  EXPECT_GT(along_shift, 0);
  // The floor and both walls: each side at most max_ties_per_wall ties.
  EXPECT_LE(ties.size(), 3u * static_cast<size_t>(WallTieOptions().max_ties_per_wall));
}

// A keyframe at `x` on part `part` seeing planes facing -x at the world offsets `offsets`.
PlaneSightings FacingWalls(int64_t id, int part, double x, const std::vector<double>& offsets) {
  PlaneSightings sightings;
  sightings.id = id;
  sightings.part = part;
  sightings.world_from_cam.translation() = Eigen::Vector3d(x, 0.0, 0.0);
  for (double offset : offsets) {
    AxisPlane plane;
    plane.normal_cam = -Eigen::Vector3d::UnitX();
    plane.offset_m = offset + x;  // on it -X = offset in the world, so -x_cam = offset + x
    plane.support = 1000;
    plane.centroid_cam = Eigen::Vector3d(-offset - x, 0.0, 0.0);
    sightings.planes.push_back(plane);
  }
  return sightings;
}

TEST(WallTies, NoTieWithinAPartAcrossAGapOrToOneOfTwoNearPlanes) {
  WallTieOptions options;
  options.min_agreeing = 1;
  const Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  // One part: nothing to tie.
  EXPECT_TRUE(
      TieWalls({FacingWalls(0, 0, 0.0, {-3.0}), FacingWalls(1, 0, 0.5, {-3.0})}, axes, options)
          .empty());
  // Two parts, the planes farther apart than max_offset_gap_m: not one wall.
  EXPECT_TRUE(
      TieWalls({FacingWalls(0, 0, 0.0, {-3.0}), FacingWalls(1, 1, 0.5, {-3.3})}, axes, options)
          .empty());
  EXPECT_EQ(
      TieWalls({FacingWalls(0, 0, 0.0, {-3.0}), FacingWalls(1, 1, 0.5, {-3.1})}, axes, options)
          .size(),
      1u);
  // The second keyframe shows two planes within min_unique_gap_m: which is the wall?
  EXPECT_TRUE(TieWalls({FacingWalls(0, 0, 0.0, {-3.0}), FacingWalls(1, 1, 0.5, {-3.1, -2.8})}, axes,
                       options)
                  .empty());
  // A plane whose centroid lies far from the other's (another room's wall in line) is not tied.
  PlaneSightings far = FacingWalls(1, 1, 0.5, {-3.0});
  far.planes[0].centroid_cam.y() = 5.0;
  EXPECT_TRUE(TieWalls({FacingWalls(0, 0, 0.0, {-3.0}), far}, axes, options).empty());
}

TEST(WallTies, APairThatDisagreesWithTheOthersIsOutvoted) {
  const Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  // Part 1's keyframes 2 and 3 see the wall 0.1 m nearer than part 0 does (the part is off);
  // keyframe 4 sees a cupboard front 0.18 m before the wall and not the wall.
  const std::vector<PlaneSightings> keyframes = {
      FacingWalls(0, 0, 0.0, {-3.0}), FacingWalls(1, 0, 0.3, {-3.0}),
      FacingWalls(2, 1, 0.6, {-2.9}), FacingWalls(3, 1, 0.9, {-2.9}),
      FacingWalls(4, 1, 1.2, {-2.82})};
  const std::vector<PlaneTie> ties = TieWalls(keyframes, axes, WallTieOptions());
  ASSERT_FALSE(ties.empty());
  for (const PlaneTie& tie : ties) {
    EXPECT_NE(tie.from, 4);
    EXPECT_NE(tie.to, 4);
  }
  // Alone, one pair is not enough.
  EXPECT_TRUE(TieWalls({keyframes[0], keyframes[2]}, axes, WallTieOptions()).empty());
}

TEST(WallTies, BadOptionsAreRefused) {
  WallTieOptions options;
  options.min_unique_gap_m = 0.1;  // under max_offset_gap_m
  EXPECT_FALSE(options.Check(nullptr));
  EXPECT_THROW(TieWalls({}, Eigen::Matrix3d::Identity(), options), InvalidArgument);
  options = WallTieOptions();
  options.sigma_m = 0.0;
  EXPECT_FALSE(options.Check(nullptr));
  EXPECT_TRUE(WallTieOptions().Check(nullptr));
}

}  // namespace
}  // namespace sightmap::slam
