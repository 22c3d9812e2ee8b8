#include "slam/axes_path.h"

#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::slam {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

Eigen::Isometry3d Motion(const Eigen::Vector3d& translation, double turn_deg) {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  // About the camera's y (down): a turn of the heading.
  motion.linear() =
      Eigen::AngleAxisd(DegToRad(turn_deg), Eigen::Vector3d::UnitY()).toRotationMatrix();
  motion.translation() = translation;
  return motion;
}

// Six poses 1 m apart along x, each seeing the building's axes (world_from_axes = identity) when
// `priors`; the step 1 -> 2 is a blind link whose rotation errs `blind_error_deg` about the
// vertical, with sigmas blind_sigma_m / blind_sigma_deg; the others are registered (1 cm, 0.3
// degrees). The chain runs 0 -> 5.
struct Corridor {
  PoseGraph graph;
  std::vector<size_t> path;
  std::vector<Matrix6d> covariances;

  Corridor(bool priors, double blind_error_deg, double blind_sigma_deg) {
    for (int i = 0; i < 6; ++i) graph.AddPose(i, Motion({1.0 * i, 0.0, 0.0}, 0.0));
    for (int i = 0; i < 5; ++i) {
      PoseGraphEdge edge;
      edge.from = i;
      edge.to = i + 1;
      const bool blind = i == 1;
      edge.to_in_from = Motion({1.0, 0.0, 0.0}, blind ? blind_error_deg : 0.0);
      edge.type = blind ? LinkType::kPrior : LinkType::kOdometry;
      covariances.push_back(blind ? DiagonalCovariance(0.16, DegToRad(blind_sigma_deg))
                                  : DiagonalCovariance(0.01, DegToRad(0.3)));
      edge.information = covariances.back().inverse();
      path.push_back(graph.AddEdge(edge));
    }
    if (!priors) return;
    RotationPrior prior;  // identity: each camera sees the axes as the world has them
    prior.sigma_rad = DegToRad(1.0);
    for (int i = 0; i < 6; ++i) graph.SetRotationPrior(i, prior);
  }

  AxesChain Chain() const {
    return ChainAlongAxes(graph, 0, path, [&](size_t edge) { return covariances.at(edge); });
  }
};

TEST(AxesPath, HeldToTheAxesABlindLinksTurnStopsAtTheNextKeyframe) {
  const AxesChain plain = Corridor(false, 12.0, 15.0).Chain();
  const AxesChain held = Corridor(true, 12.0, 15.0).Chain();
  const double plain_sigma_deg = RadToDeg(std::sqrt(plain.covariance(4, 4)));
  const double held_sigma_deg = RadToDeg(std::sqrt(held.covariance(4, 4)));
  std::printf(
      "a blind link 12 degrees off, 3 m before the end: %.3f m and %.1f degrees off plain "
      "(sigma %.1f), %.2g m and %.2g degrees held to the axes (sigma %.2f)\n",
      (plain.to_in_from.translation() - Eigen::Vector3d(5, 0, 0)).norm(),
      RotationAngleDeg(plain.to_in_from), plain_sigma_deg,
      (held.to_in_from.translation() - Eigen::Vector3d(5, 0, 0)).norm(),
      RotationAngleDeg(held.to_in_from), held_sigma_deg);
  EXPECT_EQ(plain.held_to_axes, 0);
  EXPECT_NEAR(RotationAngleDeg(plain.to_in_from), 12.0, 1e-6);
  EXPECT_GT((plain.to_in_from.translation() - Eigen::Vector3d(5, 0, 0)).norm(), 0.5);
  EXPECT_GT(plain_sigma_deg, 14.9);
  EXPECT_EQ(held.held_to_axes, 5);  // every pose after the first
  EXPECT_LT(RotationAngleDeg(held.to_in_from), 1e-6);
  EXPECT_LT((held.to_in_from.translation() - Eigen::Vector3d(5, 0, 0)).norm(), 1e-9);
  EXPECT_LT(held_sigma_deg, 3.0);
  // Across the heading: the blind link's translation sigma (0.16 m) and its rotation's lever over
  // its own metre (0.26 m) stay; that lever over the 3 m after it does not.
  std::printf("sigma across: plain %.3f m, held %.3f m\n", std::sqrt(plain.covariance(2, 2)),
              std::sqrt(held.covariance(2, 2)));
  EXPECT_LT(std::sqrt(held.covariance(2, 2)), 0.35);
  EXPECT_GT(std::sqrt(plain.covariance(2, 2)), 2.0 * std::sqrt(held.covariance(2, 2)));
}

TEST(AxesPath, AfterAChainTooUncertainToNameTheAxesNothingIsHeld) {
  // A blind link with a 35-degree sigma (above max_drift_sigma_deg): the naming after it is a
  // guess, so only the pose before it is held.
  const AxesChain chain = Corridor(true, 12.0, 35.0).Chain();
  EXPECT_EQ(chain.held_to_axes, 1);
  EXPECT_NEAR(RotationAngleDeg(chain.to_in_from), 12.0, 1e-6);
}

TEST(AxesPath, AnEdgeRunBackwardsChainsAsItsInverse) {
  const Corridor forward(true, 12.0, 15.0);
  // The same corridor with the blind link stored 2 -> 1: the inverse motion, and its covariance
  // carried into pose 2's frame (r' = -Ad(M^-1) r).
  Corridor backward(true, 12.0, 15.0);
  PoseGraph graph;
  for (int i = 0; i < 6; ++i) graph.AddPose(i, backward.graph.Pose(i));
  for (size_t e = 0; e < backward.graph.Edges().size(); ++e) {
    PoseGraphEdge edge = backward.graph.Edges()[e];
    if (e == 1) {
      const Eigen::Isometry3d inverse = edge.to_in_from.inverse();
      backward.covariances[e] =
          AdjointSe3(inverse) * backward.covariances[e] * AdjointSe3(inverse).transpose();
      edge =
          PoseGraphEdge{edge.to, edge.from, inverse, backward.covariances[e].inverse(), edge.type};
    }
    graph.AddEdge(edge);
  }
  RotationPrior prior;
  prior.sigma_rad = DegToRad(1.0);
  for (int i = 0; i < 6; ++i) graph.SetRotationPrior(i, prior);
  backward.graph = std::move(graph);
  const AxesChain a = forward.Chain();
  const AxesChain b = backward.Chain();
  EXPECT_TRUE(a.to_in_from.isApprox(b.to_in_from, 1e-9));
  EXPECT_TRUE(a.covariance.isApprox(b.covariance, 1e-6)) << a.covariance << "\n\n" << b.covariance;
  EXPECT_EQ(a.held_to_axes, b.held_to_axes);
}

TEST(AxesPath, APathThatDoesNotChainAndBadOptionsAreRefused) {
  const Corridor corridor(true, 0.0, 15.0);
  const auto covariance = [&](size_t edge) { return corridor.covariances.at(edge); };
  EXPECT_THROW(ChainAlongAxes(corridor.graph, 0, {1, 2}, covariance), Error);
  AxesChainOptions options;
  options.max_snap_deg = 45.0;
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(ChainAlongAxes(corridor.graph, 0, corridor.path, covariance, options), Error);
  options = AxesChainOptions();
  options.max_drift_sigma_deg = 0.0;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace sightmap::slam
