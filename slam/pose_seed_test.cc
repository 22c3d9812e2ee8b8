#include "slam/pose_seed.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace sightmap::slam {
namespace {

double DegToRad(double degrees) { return degrees * M_PI / 180.0; }

double AngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * 180.0 / M_PI;
}

// A walk round a 4 m x 4 m room: camera y down, turning about it by a quarter turn at each corner
// (eight poses, two a side).
std::vector<Eigen::Isometry3d> RoomWalk() {
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < 8; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    const int side = i / 2;
    pose.linear() =
        Eigen::AngleAxisd(side * M_PI / 2.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Vector3d along = pose.linear() * Eigen::Vector3d::UnitZ();
    static const Eigen::Vector3d kCorners[4] = {{0, 0, 0}, {0, 0, 4}, {4, 0, 4}, {4, 0, 0}};
    pose.translation() = kCorners[side] + along * 2.0 * (i % 2);
    poses.push_back(pose);
  }
  return poses;
}

SeedEdge Between(const std::vector<Eigen::Isometry3d>& truth, size_t from, size_t to,
                 double rotation_sigma_deg, double translation_sigma_m) {
  SeedEdge edge;
  edge.from = from;
  edge.to = to;
  edge.to_in_from = truth[from].inverse() * truth[to];
  const double sigma_rad = DegToRad(rotation_sigma_deg);
  edge.rotation_weight = 1.0 / (sigma_rad * sigma_rad);
  edge.translation_information =
      Eigen::Matrix3d::Identity() / (translation_sigma_m * translation_sigma_m);
  return edge;
}

TEST(PoseSeed, ConsistentMeasurementsGiveTheTruthFromAnyEstimate) {
  const std::vector<Eigen::Isometry3d> truth = RoomWalk();
  std::vector<SeedEdge> edges;
  for (size_t i = 0; i < truth.size(); ++i) {
    edges.push_back(Between(truth, i, (i + 1) % truth.size(), 1.0, 0.01));
  }
  // Estimates far off: each pose turned 60-130 degrees about a tilted axis and 3 m away.
  std::vector<Eigen::Isometry3d> estimates = truth;
  for (size_t i = 1; i < estimates.size(); ++i) {
    estimates[i].linear() =
        Eigen::AngleAxisd(DegToRad(60.0 + 10.0 * i), Eigen::Vector3d(1, 1, 0.5).normalized())
            .toRotationMatrix() *
        truth[i].linear();
    estimates[i].translation() += Eigen::Vector3d(3.0, -1.0, 2.0);
  }
  std::vector<bool> held(truth.size(), false);
  held[0] = true;
  const std::vector<Eigen::Isometry3d> seeded = SeedPoses(estimates, held, edges);
  ASSERT_EQ(seeded.size(), truth.size());
  for (size_t i = 0; i < truth.size(); ++i) {
    EXPECT_LT(AngleDeg(seeded[i].linear(), truth[i].linear()), 1e-3) << i;
    EXPECT_LT((seeded[i].translation() - truth[i].translation()).norm(), 1e-3) << i;
  }
}

TEST(PoseSeed, PosesNoEdgeTouchesAndHeldPosesStay) {
  const std::vector<Eigen::Isometry3d> truth = RoomWalk();
  std::vector<Eigen::Isometry3d> estimates = truth;
  estimates[2].translation().x() += 1.0;
  estimates[5].translation().x() += 1.0;  // touched by no edge
  const std::vector<SeedEdge> edges = {Between(truth, 1, 2, 1.0, 0.01)};
  std::vector<bool> held(truth.size(), false);
  held[1] = true;
  const std::vector<Eigen::Isometry3d> seeded = SeedPoses(estimates, held, edges);
  EXPECT_TRUE(seeded[1].isApprox(estimates[1]));
  EXPECT_TRUE(seeded[5].isApprox(estimates[5]));
  EXPECT_LT((seeded[2].translation() - truth[2].translation()).norm(), 1e-3);
}

}  // namespace
}  // namespace sightmap::slam
