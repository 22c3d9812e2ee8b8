#include "slam/rigid_alignment.h"

#include <random>

#include <gtest/gtest.h>

namespace sightmap::slam {
namespace {

Eigen::Isometry3d SomeMotion() {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).matrix();
  motion.translation() = Eigen::Vector3d(0.5, -0.2, 1.3);
  return motion;
}

TEST(AlignRigid, RecoversAKnownMotionExactly) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-2.0, 2.0);
  std::vector<Eigen::Vector3d> src;
  std::vector<Eigen::Vector3d> dst;
  const Eigen::Isometry3d truth = SomeMotion();
  for (int i = 0; i < 20; ++i) {
    src.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    dst.push_back(truth * src.back());
  }
  Eigen::Isometry3d estimate;
  ASSERT_TRUE(AlignRigid(src, dst, {}, &estimate));
  EXPECT_LT((estimate.matrix() - truth.matrix()).norm(), 1e-9);
}

TEST(AlignRigid, WeightsSilenceAnOutlier) {
  std::vector<Eigen::Vector3d> src = {{0, 0, 1}, {1, 0, 1}, {0, 1, 2}, {1, 1, 3}, {2, 0, 1}};
  const Eigen::Isometry3d truth = SomeMotion();
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(truth * p);
  dst[4] += Eigen::Vector3d(0.5, 0.5, 0.5);
  Eigen::Isometry3d unweighted;
  Eigen::Isometry3d weighted;
  ASSERT_TRUE(AlignRigid(src, dst, {}, &unweighted));
  ASSERT_TRUE(AlignRigid(src, dst, {1, 1, 1, 1, 0}, &weighted));
  EXPECT_GT((unweighted.translation() - truth.translation()).norm(), 0.05);
  EXPECT_LT((weighted.translation() - truth.translation()).norm(), 1e-9);
}

TEST(AlignRigid, RefusesTooFewAndCollinearPoints) {
  Eigen::Isometry3d estimate = Eigen::Isometry3d::Identity();
  EXPECT_FALSE(AlignRigid({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, {}, &estimate));
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  EXPECT_FALSE(AlignRigid(line, line, {}, &estimate));
  EXPECT_TRUE(estimate.matrix().isIdentity());
}

}  // namespace
}  // namespace sightmap::slam
