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

// The room walk's four sides as rigid parts (registered edges within a side), joined at the
// corners by bridging edges; `turn_deg` turns the side {4, 5} about the vertical (camera y) round
// pose 4, and `wrong_bridge` makes the corner edge 3 -> 4 measure a quarter turn too.
struct SidesAndCorners {
  std::vector<Eigen::Isometry3d> truth = RoomWalk();
  std::vector<Eigen::Isometry3d> estimates;
  std::vector<SeedEdge> edges;
  std::vector<bool> held = std::vector<bool>(8, false);

  SidesAndCorners(double turn_deg, bool wrong_bridge) {
    Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
    turn.linear() =
        Eigen::AngleAxisd(DegToRad(turn_deg), Eigen::Vector3d::UnitY()).toRotationMatrix();
    turn.translation() = truth[4].translation() - turn.linear() * truth[4].translation();
    held[0] = true;
    estimates = truth;
    estimates[4] = turn * truth[4];
    estimates[5] = turn * truth[5];
    for (size_t side = 0; side < 4; ++side) {
      edges.push_back(Between(truth, 2 * side, 2 * side + 1, 1.0, 0.01));
      SeedEdge corner = Between(truth, 2 * side + 1, (2 * side + 2) % 8, 15.0, 0.2);
      corner.bridging = true;
      if (wrong_bridge && side == 1) {
        corner.to_in_from.linear() =
            corner.to_in_from.linear() *
            Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
      }
      edges.push_back(corner);
    }
  }
};

TEST(PoseSeed, APartAQuarterTurnFromBothItsBridgesIsTurnedBack) {
  const SidesAndCorners walk(90.0, false);
  int turned_parts = -1;
  const std::vector<Eigen::Isometry3d> turned =
      TurnPartsToTheirBridges(walk.estimates, walk.held, walk.edges, Eigen::Matrix3d::Identity(),
                              DegToRad(30.0), &turned_parts);
  EXPECT_EQ(turned_parts, 1);
  for (size_t i = 0; i < walk.truth.size(); ++i) {
    EXPECT_LT(AngleDeg(turned[i].linear(), walk.truth[i].linear()), 1e-6) << i;
    EXPECT_LT((turned[i].translation() - walk.truth[i].translation()).norm(), 1e-6) << i;
  }
}

// Held in the part that is off, pose 4 keeps the map's frame: the rest turns to it instead.
TEST(PoseSeed, APartHoldingAHeldPoseIsNotTurned) {
  SidesAndCorners walk(90.0, false);
  walk.held.assign(8, false);
  walk.held[4] = true;
  int turned_parts = -1;
  const std::vector<Eigen::Isometry3d> turned =
      TurnPartsToTheirBridges(walk.estimates, walk.held, walk.edges, Eigen::Matrix3d::Identity(),
                              DegToRad(30.0), &turned_parts);
  EXPECT_EQ(turned_parts, 1);
  EXPECT_TRUE(turned[4].isApprox(walk.estimates[4]));
  // The whole walk as the truth, moved rigidly to where pose 4 is held; positions to a centimetre
  // or so (the rest turned about pose 0 lands metres from there, and the solve keeps a faint
  // anchor to where a pose was).
  const Eigen::Isometry3d frame = walk.estimates[4] * walk.truth[4].inverse();
  for (size_t i = 0; i < walk.truth.size(); ++i) {
    EXPECT_LT(AngleDeg(turned[i].linear(), (frame * walk.truth[i]).linear()), 1e-6) << i;
    EXPECT_LT((turned[i].translation() - (frame * walk.truth[i]).translation()).norm(), 0.03) << i;
  }
}

TEST(PoseSeed, APartTurnsOnlyWhenMostOfItsBridgesSaySo) {
  // Right where it is, one bridge of two says turn: a tie, no turn.
  int turned_parts = -1;
  const SidesAndCorners right(0.0, true);
  const std::vector<Eigen::Isometry3d> kept =
      TurnPartsToTheirBridges(right.estimates, right.held, right.edges, Eigen::Matrix3d::Identity(),
                              DegToRad(30.0), &turned_parts);
  EXPECT_EQ(turned_parts, 0);
  EXPECT_LT(AngleDeg(kept[4].linear(), right.truth[4].linear()), 1e-6);
  // Turned 50 degrees: no naming of the axes lies within 30 degrees of what its bridges say.
  const SidesAndCorners between(50.0, false);
  TurnPartsToTheirBridges(between.estimates, between.held, between.edges,
                          Eigen::Matrix3d::Identity(), DegToRad(30.0), &turned_parts);
  EXPECT_EQ(turned_parts, 0);
}

}  // namespace
}  // namespace sightmap::slam
