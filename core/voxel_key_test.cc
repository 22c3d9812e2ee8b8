#include "core/voxel_key.h"

#include <limits>

#include <gtest/gtest.h>

namespace sightmap {
namespace {

TEST(VoxelKey, RoundTripsToTheCellCornerOnBothSidesOfTheOrigin) {
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.013, -0.013, 0.0), Eigen::Vector3d(-1234.567, 89.01, -0.0001),
        Eigen::Vector3d(20000.0, -20000.0, 3.3)}) {
    const std::optional<uint64_t> key = VoxelKeyOf(p, 0.02);
    ASSERT_TRUE(key.has_value());
    const Eigen::Vector3d corner = VoxelCorner(*key, 0.02);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_LE(corner[axis], p[axis] + 1e-9);
      EXPECT_GT(corner[axis] + 0.02, p[axis]);
    }
  }
  // Neighbouring cells get different keys, points of one cell the same.
  EXPECT_NE(VoxelKeyOf({0.019, 0.0, 0.0}, 0.02), VoxelKeyOf({0.021, 0.0, 0.0}, 0.02));
  EXPECT_EQ(VoxelKeyOf({0.001, 0.0, 0.0}, 0.02), VoxelKeyOf({0.019, 0.0, 0.0}, 0.02));
  EXPECT_NE(VoxelKeyOf({-0.001, 0.0, 0.0}, 0.02), VoxelKeyOf({0.001, 0.0, 0.0}, 0.02));
}

TEST(VoxelKey, OutOfRangeOrNotFiniteHasNoKey) {
  EXPECT_FALSE(VoxelKeyOf({30000.0, 0.0, 0.0}, 0.02).has_value());  // beyond 21 km
  EXPECT_FALSE(VoxelKeyOf({0.0, -30000.0, 0.0}, 0.02).has_value());
  EXPECT_FALSE(VoxelKeyOf({0.0, 0.0, std::numeric_limits<double>::quiet_NaN()}, 0.02).has_value());
  EXPECT_FALSE(VoxelKeyOf({std::numeric_limits<double>::infinity(), 0.0, 0.0}, 0.02).has_value());
  EXPECT_TRUE(VoxelKeyOf({30000.0, 0.0, 0.0}, 0.05).has_value());  // within 52 km at 5 cm
}

}  // namespace
}  // namespace sightmap
