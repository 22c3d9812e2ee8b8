#include "slam/pose_graph.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/link_type.h"
#include "core/rotation.h"
#include "slam/synthetic_pose_graph.h"

namespace sightmap::slam {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using synthetic::Information;
using synthetic::PositionRmse;

Eigen::Isometry3d Translation(double x, double y = 0.0, double z = 0.0) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(x, y, z);
  return pose;
}

PoseGraphEdge MakeEdge(int64_t from, int64_t to, const Eigen::Isometry3d& to_in_from,
                       const Matrix6d& information, LinkType type = LinkType::kOdometry) {
  PoseGraphEdge edge;
  edge.from = from;
  edge.to = to;
  edge.to_in_from = to_in_from;
  edge.information = information;
  edge.type = type;
  return edge;
}

// Information weighting only x by `weight` (the other five directions are measured as zero
// and firmly held there).
Matrix6d XWeight(double weight) {
  Matrix6d information = 1e6 * Matrix6d::Identity();
  information(0, 0) = weight;
  return information;
}

// The error of an edge is r = (t, w) with E = Exp(r) * M, translation first and the rotation on
// the left (RegistrationResult::information's parameterisation): with a dense, coupled
// information, the chi-square of a pose pair built as Exp(delta) * M must be delta^T W delta.
TEST(PoseGraph, ChiSquareUsesTheRegistrationParameterisation) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  Matrix6d random;
  for (int i = 0; i < 36; ++i) random(i / 6, i % 6) = normal(rng);
  const Matrix6d information = random * random.transpose() + 0.1 * Matrix6d::Identity();

  const Eigen::Isometry3d world_from_a =
      ExpSe3((Vector6d() << 0.3, -1.0, 0.5, 0.2, -0.4, 1.1).finished());
  const Eigen::Isometry3d measured =
      ExpSe3((Vector6d() << 1.2, 0.4, -0.3, -0.3, 0.5, 0.7).finished());
  const Vector6d delta = (Vector6d() << 0.01, -0.02, 0.015, 0.004, -0.006, 0.003).finished();

  PoseGraph graph;
  graph.AddPose(1, world_from_a);
  graph.AddPose(2, world_from_a * ExpSe3(delta) * measured);
  graph.AddEdge(MakeEdge(1, 2, measured, information));
  const double expected = delta.dot(information * delta);
  EXPECT_NEAR(graph.EdgeChi2(0), expected, 1e-9 * expected);

  // The same delta applied on the right of M, or with translation and rotation swapped, scores
  // differently (the check above can fail).
  graph.SetPose(2, world_from_a * measured * ExpSe3(delta));
  EXPECT_GT(std::abs(graph.EdgeChi2(0) - expected), 0.01 * expected);
}

// x1 and x2 on a line from x0 = 0: 0->1 measures 1.0 (weight 1), 1->2 measures 1.0 (weight 1),
// 0->2 measures 2.6 (weight 2). Minimising (x1 - 1)^2 + (x2 - x1 - 1)^2 + 2 (x2 - 2.6)^2 gives
// x2 = 2 x1 and 3 x2 - x1 = 6.2, so x1 = 1.24, x2 = 2.48, and the cost
// 0.5 * (0.24^2 + 0.24^2 + 2 * 0.12^2) = 0.072.
TEST(PoseGraph, ChainMatchesTheHandSolvedLeastSquares) {
  PoseGraph graph;
  graph.AddPose(0, Translation(0.0));
  graph.AddPose(1, Translation(0.7, 0.1));
  graph.AddPose(2, Translation(3.1, -0.2, 0.3));
  graph.AddEdge(MakeEdge(0, 1, Translation(1.0), XWeight(1.0)));
  graph.AddEdge(MakeEdge(1, 2, Translation(1.0), XWeight(1.0)));
  graph.AddEdge(MakeEdge(0, 2, Translation(2.6), XWeight(2.0)));
  const PoseGraphSummary summary = graph.Optimize();
  EXPECT_TRUE(summary.converged);
  EXPECT_TRUE(summary.usable);
  EXPECT_EQ(summary.solves, 1);
  EXPECT_NEAR(graph.Pose(1).translation().x(), 1.24, 1e-6);
  EXPECT_NEAR(graph.Pose(2).translation().x(), 2.48, 1e-6);
  EXPECT_NEAR(graph.Pose(1).translation().y(), 0.0, 1e-6);
  EXPECT_NEAR(graph.Pose(2).translation().z(), 0.0, 1e-6);
  EXPECT_NEAR(summary.final_cost, 0.072, 1e-6);
  EXPECT_GT(summary.initial_cost, summary.final_cost);
  // Pose 0 is the gauge (lowest id, nothing fixed): exactly where it was.
  EXPECT_TRUE(graph.Pose(0).isApprox(Translation(0.0), 0.0));
}

// Two conflicting measurements of the same edge: the information-weighted mean.
TEST(PoseGraph, ConflictingMeasurementsGiveTheWeightedMean) {
  PoseGraph graph;
  graph.AddPose(5, Translation(0.0));
  graph.AddPose(9, Translation(0.0));
  graph.AddEdge(MakeEdge(5, 9, Translation(1.0), XWeight(100.0)));
  graph.AddEdge(MakeEdge(5, 9, Translation(1.3), XWeight(300.0)));
  // To the last digits: the default stops when the cost falls by less than 1e-6 of itself,
  // 0.1 mm short here, where the conflict leaves a large cost.
  PoseGraphOptions exact;
  exact.function_tolerance = 1e-12;
  graph.Optimize(exact);
  EXPECT_NEAR(graph.Pose(9).translation().x(), (100.0 * 1.0 + 300.0 * 1.3) / 400.0, 1e-6);
}

// A plane tie (two keyframes seeing one wall) holds a pose along its normal only: a prior that
// put pose 2 0.2 m off in x and y (sigma 0.3 m) is corrected in x by a tie along the turned
// pose's x normal, and left alone in y.
TEST(PoseGraph, APlaneTieHoldsAPoseAlongItsNormalOnly) {
  PoseGraph graph;
  Eigen::Isometry3d turned = Translation(0.0);
  turned.linear() = Eigen::AngleAxisd(DegToRad(90.0), Eigen::Vector3d::UnitZ()).matrix();
  graph.AddPose(1, turned);
  graph.AddPose(2, Translation(0.0));
  Matrix6d information = 1e6 * Matrix6d::Identity();
  information.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / (0.3 * 0.3);
  // Truth: pose 2 at world (1, 0, 0); measured at (1.2, 0.2, 0).
  graph.AddEdge(
      MakeEdge(1, 2, turned.inverse() * Translation(1.2, 0.2), information, LinkType::kPrior));
  PlaneTie tie;
  tie.from = 1;
  tie.to = 2;
  // The world's x is the turned pose's -y.
  tie.normal_in_from = -Eigen::Vector3d::UnitY();
  tie.offset_m = 1.0;
  tie.sigma_m = 0.01;
  graph.SetPlaneTies({tie});
  EXPECT_EQ(graph.NumPlaneTies(), 1u);
  graph.Optimize();
  EXPECT_NEAR(graph.Pose(2).translation().x(), 1.0, 0.005);
  EXPECT_NEAR(graph.Pose(2).translation().y(), 0.2, 0.005);
  tie.to = 3;
  EXPECT_THROW(graph.SetPlaneTies({tie}), InvalidArgument);
  tie.to = 2;
  tie.sigma_m = 0.0;
  EXPECT_THROW(graph.SetPlaneTies({tie}), InvalidArgument);
  EXPECT_EQ(graph.NumPlaneTies(), 1u);
}

// A revised measurement replaces the old one in the next optimisation; a bad one is refused and
// leaves the edge as it was.
TEST(PoseGraph, ARevisedMeasurementReplacesTheOldOne) {
  PoseGraph graph;
  graph.AddPose(0, Translation(0.0));
  graph.AddPose(1, Translation(0.0));
  graph.AddEdge(MakeEdge(0, 1, Translation(1.0), XWeight(100.0), LinkType::kPrior));
  graph.SetEdgeMeasurement(0, Translation(0.4), XWeight(400.0));
  PoseGraphOptions exact;
  exact.function_tolerance = 1e-12;
  graph.Optimize(exact);
  EXPECT_NEAR(graph.Pose(1).translation().x(), 0.4, 1e-6);
  EXPECT_EQ(graph.Edges()[0].information(0, 0), 400.0);
  EXPECT_EQ(graph.Edges()[0].type, LinkType::kPrior);

  Eigen::Isometry3d not_rigid = Translation(2.0);
  not_rigid.linear() *= 2.0;
  EXPECT_THROW(graph.SetEdgeMeasurement(0, not_rigid, XWeight(1.0)), Error);
  EXPECT_THROW(graph.SetEdgeMeasurement(0, Translation(2.0), -XWeight(1.0)), Error);
  EXPECT_THROW(graph.SetEdgeMeasurement(1, Translation(2.0), XWeight(1.0)), Error);
  EXPECT_NEAR(graph.Edges()[0].to_in_from.translation().x(), 0.4, 1e-12);
  EXPECT_EQ(graph.Edges()[0].information(0, 0), 400.0);
}

// Three poses 1 m apart, truly unrotated; the step 1 -> 2 measures an 8 degree turn that did not
// happen, with the loose rotation of a motion-model guess (5 degrees). Each pose's depth sees the
// building's axes as the pose's own axes (pose 2's named 90 degrees round: the same axes), and
// the priors (1 degree) take the turn out. A prior farther from the estimate than its deviation
// bound is not used.
TEST(PoseGraph, RotationPriorsFromTheBuildingsAxesTakeOutAFalseTurn) {
  const auto solve = [](double max_deviation_deg, bool priors) {
    PoseGraph graph;
    const Eigen::Isometry3d turn(Eigen::AngleAxisd(DegToRad(8.0), Eigen::Vector3d::UnitY()));
    graph.AddPose(0, Translation(0.0));
    graph.AddPose(1, Translation(1.0));
    graph.AddPose(2, Translation(2.0) * turn);
    graph.AddEdge(MakeEdge(0, 1, Translation(1.0), Information(0.01, DegToRad(0.2))));
    graph.AddEdge(
        MakeEdge(1, 2, Translation(1.0) * turn, Information(0.1, DegToRad(5.0)), LinkType::kPrior));
    if (priors) {
      RotationPrior prior;
      prior.sigma_rad = DegToRad(1.0);
      prior.max_deviation_rad = DegToRad(max_deviation_deg);
      graph.SetRotationPrior(0, prior);  // places the axes: pose 0 is held
      graph.SetRotationPrior(1, prior);
      prior.cam_from_axes = Eigen::AngleAxisd(DegToRad(90.0), Eigen::Vector3d::UnitY()).matrix();
      graph.SetRotationPrior(2, prior);
      EXPECT_EQ(graph.NumRotationPriors(), 3u);
    }
    PoseGraphOptions exact;
    exact.function_tolerance = 1e-12;
    graph.Optimize(exact);
    return RadToDeg(Eigen::AngleAxisd(graph.Pose(2).linear()).angle());
  };
  EXPECT_NEAR(solve(10.0, false), 8.0, 0.05);
  const double corrected = solve(10.0, true);
  EXPECT_LT(corrected, 0.5);
  EXPECT_NEAR(solve(5.0, true), 8.0, 0.05);  // pose 2's prior is too far: not used

  PoseGraph graph;
  graph.AddPose(0, Translation(0.0));
  EXPECT_THROW(graph.SetRotationPrior(1, RotationPrior()), Error);
  RotationPrior not_a_rotation;
  not_a_rotation.cam_from_axes *= 2.0;
  EXPECT_THROW(graph.SetRotationPrior(0, not_a_rotation), Error);
  RotationPrior no_sigma;
  no_sigma.sigma_rad = 0.0;
  EXPECT_THROW(graph.SetRotationPrior(0, no_sigma), Error);
}

// A blind step the motion model turned 100 degrees the wrong way, and a loop that says so. The
// rotation priors, named from the turned estimate, take the axes' naming 90 degrees off (10
// degrees from the estimate, within the bound) and hold the stretch there; the loop then looks
// false and is switched off. Solved again by the loops alone first, the namings come out right
// and the loop stays.
TEST(PoseGraph, ALoopTurnsBackAStretchThePriorsWouldHoldInAWrongNaming) {
  const auto solve = [](bool retry) {
    PoseGraph graph;
    const Eigen::Isometry3d turn(Eigen::AngleAxisd(DegToRad(100.0), Eigen::Vector3d::UnitY()));
    graph.AddPose(0, Translation(0.0));
    graph.AddPose(1, Translation(1.0));
    graph.AddPose(2, Translation(1.0) * turn * Translation(1.0));
    graph.AddPose(3, Translation(1.0) * turn * Translation(2.0));
    graph.AddEdge(MakeEdge(0, 1, Translation(1.0), Information(0.003, 0.001)));
    graph.AddEdge(MakeEdge(1, 2, turn * Translation(1.0), Information(0.5, DegToRad(60.0)),
                           LinkType::kPrior));
    graph.AddEdge(MakeEdge(2, 3, Translation(1.0), Information(0.003, 0.001)));
    const size_t loop = graph.AddEdge(MakeEdge(
        3, 0, Translation(-3.0), Information(0.05, DegToRad(10.0)), LinkType::kLoopClosure));
    RotationPrior prior;  // every camera sees the axes as they are: none of them turned
    prior.sigma_rad = DegToRad(1.0);
    prior.max_deviation_rad = DegToRad(15.0);
    for (int id = 0; id < 4; ++id) graph.SetRotationPrior(id, prior);
    PoseGraphOptions options;
    options.retry_rejected_loops_without_priors = retry;
    graph.Optimize(options);
    return std::make_pair(graph.EdgeActive(loop),
                          RadToDeg(Eigen::AngleAxisd(graph.Pose(3).linear()).angle()));
  };
  const auto [held_loop, held_deg] = solve(false);
  EXPECT_FALSE(held_loop);
  EXPECT_NEAR(held_deg, 90.0, 1.0);
  const auto [retried_loop, retried_deg] = solve(true);
  EXPECT_TRUE(retried_loop);
  EXPECT_LT(retried_deg, 1.0);
}

// Two halves of a walk (poses 0-2 and 3-5, 1 m apart on a line), each firm, joined only by two
// blind prior links (15 degrees, 0.5 m) that measure the second half turned by `link_turn_deg`
// about the vertical; the second half starts turned by `start_turn_deg`. Every camera sees the
// building's axes as they are (none of them turned).
PoseGraph HalvesJoinedByBlindLinks(double start_turn_deg, double link_turn_deg) {
  PoseGraph graph;
  const Eigen::Isometry3d start_turn(
      Eigen::AngleAxisd(DegToRad(start_turn_deg), Eigen::Vector3d::UnitY()));
  const Eigen::Isometry3d link_turn(
      Eigen::AngleAxisd(DegToRad(link_turn_deg), Eigen::Vector3d::UnitY()));
  for (int i = 0; i < 3; ++i) graph.AddPose(i, Translation(i));
  for (int i = 3; i < 6; ++i)
    graph.AddPose(i, Translation(3.0) * start_turn * Translation(i - 3.0));
  const Matrix6d firm = Information(0.003, 0.001);
  const Matrix6d blind = Information(0.5, DegToRad(15.0));
  for (int i : {0, 1, 3, 4}) graph.AddEdge(MakeEdge(i, i + 1, Translation(1.0), firm));
  graph.AddEdge(MakeEdge(2, 3, Translation(1.0) * link_turn, blind, LinkType::kPrior));
  graph.AddEdge(MakeEdge(5, 0, link_turn.inverse() * Translation(-5.0), blind, LinkType::kPrior));
  RotationPrior prior;
  prior.sigma_rad = DegToRad(1.0);
  prior.max_deviation_rad = DegToRad(15.0);
  for (int id = 0; id < 6; ++id) graph.SetRotationPrior(id, prior);
  return graph;
}

PoseGraphOptions WithTheMappersOdometryLoss() {
  PoseGraphOptions options;
  options.odometry_loss_scale = options.loop_loss_scale;
  return options;
}

// The links measure the truth, but the second half starts turned 100 degrees: its priors then
// lie 10 degrees from the naming a quarter turn off and hold it there against the links, whose
// robust loss hears them less the farther they are off. Seeded by the links alone, the part is
// solved where they put it, and that fits links and priors better.
TEST(PoseGraph, TheSeededSolveTurnsBackAHalfItsPriorsHoldInAWrongNaming) {
  const auto solve = [](bool seeded) {
    PoseGraph graph = HalvesJoinedByBlindLinks(100.0, 0.0);
    const PoseGraphOptions options = WithTheMappersOdometryLoss();
    const PoseGraphSummary summary =
        seeded ? graph.OptimizeAroundSeeded(0, options) : graph.OptimizeAround(0, options);
    return std::make_pair(summary.seeded,
                          RadToDeg(Eigen::AngleAxisd(graph.Pose(4).linear()).angle()));
  };
  const auto [plain_seeded, plain_deg] = solve(false);
  EXPECT_FALSE(plain_seeded);
  EXPECT_NEAR(plain_deg, 90.0, 1.0);
  const auto [seeded, seeded_deg] = solve(true);
  EXPECT_TRUE(seeded);
  EXPECT_LT(seeded_deg, 0.5);
}

// Both blind links measure the second half turned 25 degrees, and it starts where they put it:
// there its priors lie beyond their 15-degree bound and take no part, and the seed from the links
// alone puts it there again. The seed that turns each part to its axes (priors named within
// seeded_max_axes_deviation_deg) turns it back.
TEST(PoseGraph, TheSeededSolveTurnsAHalfTheLinksTurnedToItsAxes) {
  const auto solve = [](double seeded_max_axes_deviation_deg) {
    PoseGraph graph = HalvesJoinedByBlindLinks(25.0, 25.0);
    PoseGraphOptions options = WithTheMappersOdometryLoss();
    options.seeded_max_axes_deviation_deg = seeded_max_axes_deviation_deg;
    graph.OptimizeAroundSeeded(0, options);
    return RadToDeg(Eigen::AngleAxisd(graph.Pose(4).linear()).angle());
  };
  EXPECT_GT(solve(0.0), 10.0);
  EXPECT_LT(solve(30.0), 1.0);
}

// Four poses 1 m apart on a line, each tied to the next and the one after (as the mapper links a
// keyframe to the two before it), all exact and firm (3 mm) but the step 1 -> 2, 10 cm off. In
// plain least squares the wrong step shares its error with the two paths around it; with the
// odometry loss they outvote it.
TEST(PoseGraph, TheOdometryLossLetsTwoPathsOutvoteAWrongStep) {
  const auto solve = [](double odometry_loss_scale) {
    PoseGraph graph;
    for (int i = 0; i < 4; ++i) graph.AddPose(i, Translation(i));
    const Matrix6d firm = Information(0.003, 0.001);
    for (int i = 0; i + 1 < 4; ++i) {
      graph.AddEdge(MakeEdge(i, i + 1, Translation(i == 1 ? 1.1 : 1.0), firm));
      if (i + 2 < 4) graph.AddEdge(MakeEdge(i, i + 2, Translation(2.0), firm));
    }
    PoseGraphOptions options;
    options.odometry_loss_scale = odometry_loss_scale;
    graph.Optimize(options);
    double worst_m = 0.0;
    for (int i = 0; i < 4; ++i) {
      worst_m = std::max(worst_m, std::abs(graph.Pose(i).translation().x() - i));
    }
    return worst_m;
  };
  const double plain_m = solve(0.0);
  const double robust_m = solve(4.74);
  std::cout << "[ figures  ] a step 10 cm off among exact ones: worst pose error " << plain_m
            << " m plain, " << robust_m << " m with the odometry loss\n";
  EXPECT_GT(plain_m, 0.02);
  EXPECT_LT(robust_m, 0.002);
}

// One lap of a circle (40 poses, 3 m radius) with noisy odometry (1 cm, 0.6 degree per step),
// and the last pose closed onto the first by an exact, firm loop edge; 40 seeds. At the
// least-squares optimum the summed chi-square of all edges follows a chi-square distribution
// with 6 degrees of freedom (the loop's redundancy), mean 6: a check that the optimum is reached
// and that the noise model and the residual agree.
TEST(PoseGraph, LoopClosureRemovesOdometryDrift) {
  constexpr int kSeeds = 40;
  double before = 0.0, after = 0.0, chi2 = 0.0, worst_closure = 0.0, time_s = 0.0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    synthetic::CircleOptions options;
    options.poses_per_lap = 40;
    options.odometry_sigma_m = 0.01;
    options.odometry_sigma_rad = 0.01;
    options.close_last_onto_first = true;
    options.loop_sigma_m = 0.001;
    options.loop_sigma_rad = 0.0005;
    options.seed = static_cast<uint64_t>(seed);
    synthetic::Scene scene = synthetic::MakeCircleScene(options);
    before += PositionRmse(scene.graph, scene.truth) / kSeeds;
    const PoseGraphSummary summary = scene.graph.Optimize();
    after += PositionRmse(scene.graph, scene.truth) / kSeeds;
    EXPECT_TRUE(summary.converged) << seed;
    EXPECT_TRUE(summary.rejected_edges.empty()) << seed;
    for (double edge_chi2 : summary.edge_chi2) chi2 += edge_chi2 / kSeeds;
    time_s += summary.time_s;
    // The loop itself closes.
    worst_closure = std::max(worst_closure,
                             ((scene.graph.Pose(39).inverse() * scene.graph.Pose(0)).translation() -
                              (scene.truth[39].inverse() * scene.truth[0]).translation())
                                 .norm());
  }
  std::cout << "[ figures  ] circle loop, mean of " << kSeeds << " seeds: position RMSE " << before
            << " m before, " << after << " m after, summed chi2 " << chi2
            << ", worst loop closure error " << worst_closure << " m, " << time_s / kSeeds * 1e3
            << " ms per graph\n";
  EXPECT_LT(after, 0.45 * before);  // measured 0.37: one loop cannot undo the heading drift mid-lap
  EXPECT_LT(after, 0.13);
  EXPECT_GT(chi2, 4.0);  // the mean of 40 draws of chi2(6) has a standard deviation of 0.55
  EXPECT_LT(chi2, 8.0);
  EXPECT_LT(worst_closure, 0.005);
}

// Odometry that claims to be more precise than it is makes a correct loop inconsistent: its
// chi-square at the plain least-squares optimum exceeds max_loop_chi2 and it is switched off.
// Honest (1x) and mildly optimistic (3x) informations keep it.
TEST(PoseGraph, OverconfidentOdometryLosesTheLoop) {
  for (double factor : {1.0, 3.0, 10.0, 30.0}) {
    synthetic::CircleOptions options;
    options.poses_per_lap = 40;
    options.odometry_sigma_m = 0.01;
    options.odometry_sigma_rad = 0.01;
    options.odometry_overconfidence = factor;
    options.close_last_onto_first = true;
    options.seed = 3;
    synthetic::Scene scene = synthetic::MakeCircleScene(options);
    // Plain least squares (no loss, no switch-off): the loop's chi-square at the optimum.
    PoseGraph plain = scene.graph;
    PoseGraphOptions plain_options;
    plain_options.loop_loss_scale = 1e9;
    plain_options.max_loop_chi2 = std::numeric_limits<double>::infinity();
    plain.Optimize(plain_options);
    const double plain_chi2 = plain.EdgeChi2(scene.loop_edges[0]);
    const double before = PositionRmse(scene.graph, scene.truth);
    const double chi2_before = scene.graph.EdgeChi2(scene.loop_edges[0]);
    const PoseGraphSummary summary = scene.graph.Optimize();
    std::cout << "[ figures  ] odometry " << factor << "x overconfident: loop chi2 " << chi2_before
              << " at the start, " << plain_chi2 << " at the least-squares optimum, "
              << (summary.rejected_edges.empty() ? "kept" : "switched off") << ", RMSE " << before
              << " -> " << PositionRmse(scene.graph, scene.truth) << " m\n";
    const bool consistent = plain_chi2 < PoseGraphOptions().max_loop_chi2;
    EXPECT_EQ(consistent, factor < 5.0) << factor;
    EXPECT_EQ(summary.rejected_edges.empty(), consistent) << factor;
  }
}

// Two laps (2 x 40 poses) with five correct loops between the laps, then two false loops: a
// subtle one, 10 -> 30 measured 35 cm and 7 degrees off the truth, and a gross one claiming
// that pose 25, on the far side of the 6 m circle, is 30 cm in front of pose 5.
TEST(PoseGraph, FalseLoopsAreSwitchedOffAndDoNotBendTheMap) {
  synthetic::CircleOptions options;
  options.poses_per_lap = 40;
  options.laps = 2;
  options.loop_every = 8;
  options.seed = 11;
  const synthetic::Scene clean_scene = synthetic::MakeCircleScene(options);
  ASSERT_EQ(clean_scene.loop_edges.size(), 5u);
  const std::vector<Eigen::Isometry3d>& truth = clean_scene.truth;

  PoseGraph clean = clean_scene.graph;
  const double before = PositionRmse(clean, truth);
  const PoseGraphSummary clean_summary = clean.Optimize();
  const double clean_rmse = PositionRmse(clean, truth);
  EXPECT_TRUE(clean_summary.rejected_edges.empty());
  EXPECT_LT(clean_rmse, before);

  const Matrix6d loop_information = Information(options.loop_sigma_m, options.loop_sigma_rad);
  const PoseGraphEdge subtle =
      MakeEdge(10, 30,
               ExpSe3((Vector6d() << 0.25, -0.2, 0.15, 0.0, 0.05, 0.1).finished()) *
                   truth[10].inverse() * truth[30],
               loop_information, LinkType::kLoopClosure);
  const PoseGraphEdge gross =
      MakeEdge(5, 25, ExpSe3((Vector6d() << 0.0, 0.0, 0.3, 0.0, 0.09, 0.0).finished()),
               loop_information, LinkType::kLoopClosure);
  auto largest_difference = [&](const PoseGraph& graph) {
    double largest = 0.0;
    for (size_t i = 0; i < truth.size(); ++i) {
      const auto id = static_cast<int64_t>(i);
      largest =
          std::max(largest, (graph.Pose(id).translation() - clean.Pose(id).translation()).norm());
    }
    return largest;
  };

  // Without the consistency check the false loops stay in (Cauchy-weighted) and bend the map.
  PoseGraph unchecked = clean_scene.graph;
  unchecked.AddEdge(subtle);
  unchecked.AddEdge(gross);
  PoseGraphOptions no_rejection;
  no_rejection.max_loop_chi2 = std::numeric_limits<double>::infinity();
  const PoseGraphSummary unchecked_summary = unchecked.Optimize(no_rejection);
  EXPECT_TRUE(unchecked_summary.rejected_edges.empty());

  PoseGraph graph = clean_scene.graph;
  const size_t subtle_index = graph.AddEdge(subtle);
  const size_t gross_index = graph.AddEdge(gross);
  const PoseGraphSummary summary = graph.Optimize();
  const double rmse = PositionRmse(graph, truth);
  std::cout << "[ figures  ] two laps: RMSE " << before << " m before, " << clean_rmse
            << " m clean, " << PositionRmse(unchecked, truth)
            << " m with the false loops kept (chi2 " << unchecked_summary.edge_chi2[subtle_index]
            << " and " << unchecked_summary.edge_chi2[gross_index] << ", largest shift "
            << largest_difference(unchecked) << " m), " << rmse
            << " m with them switched off (largest shift " << largest_difference(graph) << " m, "
            << summary.solves << " solves, " << summary.time_s * 1e3 << " ms)\n";
  ASSERT_EQ(summary.rejected_edges.size(), 2u);
  EXPECT_EQ(summary.rejected_edges[0], gross_index);  // the worst goes first
  EXPECT_EQ(summary.rejected_edges[1], subtle_index);
  EXPECT_FALSE(graph.EdgeActive(subtle_index));
  EXPECT_FALSE(graph.EdgeActive(gross_index));
  for (size_t loop : clean_scene.loop_edges) EXPECT_TRUE(graph.EdgeActive(loop));
  EXPECT_EQ(summary.solves, 3);
  EXPECT_NEAR(rmse, clean_rmse, 0.1 * clean_rmse);
  EXPECT_LT(largest_difference(graph), 0.1 * clean_rmse);
  EXPECT_GT(largest_difference(unchecked), 10.0 * largest_difference(graph));

  // Switched-off edges stay off in later calls, until the caller turns them back on.
  const PoseGraphSummary again = graph.Optimize();
  EXPECT_TRUE(again.rejected_edges.empty());
  EXPECT_FALSE(graph.EdgeActive(subtle_index));
  EXPECT_EQ(again.edge_chi2[subtle_index], 0.0);
  graph.SetEdgeActive(subtle_index, true);
  const PoseGraphSummary rechecked = graph.Optimize();
  ASSERT_EQ(rechecked.rejected_edges.size(), 1u);
  EXPECT_EQ(rechecked.rejected_edges[0], subtle_index);
}

// Two chains that share no edge, nothing fixed: each holds its lowest id, and both come out
// consistent with their measurements. A pose without edges does not move.
TEST(PoseGraph, DisconnectedComponentsEachHoldTheirLowestId) {
  const Eigen::Isometry3d step = ExpSe3((Vector6d() << 0.5, 0.1, 0.0, 0.0, 0.0, 0.2).finished());
  const Eigen::Isometry3d start_a = Translation(1.0, 2.0, 3.0);
  const Eigen::Isometry3d start_b =
      ExpSe3((Vector6d() << -4.0, 0.0, 1.0, 0.3, 0.0, 0.0).finished());
  const Eigen::Isometry3d nudge =
      ExpSe3((Vector6d() << 0.05, -0.03, 0.02, 0.02, 0.01, -0.03).finished());
  const Eigen::Isometry3d lonely = Translation(9.0, 9.0, 9.0);
  PoseGraph graph;
  for (int64_t i = 0; i < 5; ++i) {
    graph.AddPose(i, i == 0 ? start_a : nudge * graph.Pose(i - 1) * step);
    graph.AddPose(10 + i, i == 0 ? start_b : graph.Pose(9 + i) * step * nudge);
  }
  graph.AddPose(99, lonely);
  for (int64_t i = 0; i < 4; ++i) {
    graph.AddEdge(MakeEdge(i, i + 1, step, Matrix6d::Identity()));
    graph.AddEdge(MakeEdge(10 + i, 11 + i, step, Matrix6d::Identity()));
  }
  const PoseGraphSummary summary = graph.Optimize();
  EXPECT_TRUE(summary.converged);
  EXPECT_LT(summary.final_cost, 1e-12);
  EXPECT_TRUE(graph.Pose(0).isApprox(start_a, 0.0));
  EXPECT_TRUE(graph.Pose(10).isApprox(start_b, 0.0));
  EXPECT_TRUE(graph.Pose(99).isApprox(lonely, 0.0));
  for (int64_t i = 1; i < 5; ++i) {
    EXPECT_TRUE(graph.Pose(i).isApprox(graph.Pose(i - 1) * step, 1e-6)) << i;
    EXPECT_TRUE(graph.Pose(10 + i).isApprox(graph.Pose(9 + i) * step, 1e-6)) << i;
  }

  // A fixed pose is the gauge of its component instead: 12 stays, 10 moves.
  const Eigen::Isometry3d twelve = graph.Pose(12) * nudge;
  graph.SetPose(12, twelve);
  graph.SetFixed(12);
  EXPECT_TRUE(graph.IsFixed(12));
  graph.Optimize();
  EXPECT_TRUE(graph.Pose(12).isApprox(twelve, 0.0));
  EXPECT_FALSE(graph.Pose(10).isApprox(start_b, 1e-3));
  EXPECT_TRUE(graph.Pose(0).isApprox(start_a, 0.0));
  EXPECT_TRUE(graph.Pose(14).isApprox(twelve * step * step, 1e-6));
}

TEST(PoseGraph, OptimizeAroundMovesOnlyThePartTiedToThePose) {
  // Two chains, both off their optimum, and a false loop in the second: optimising around a pose
  // of the first settles the first only; the second keeps its poses and its false loop.
  const Eigen::Isometry3d step = Translation(1.0);
  const Eigen::Isometry3d nudge =
      ExpSe3((Vector6d() << 0.05, -0.03, 0.02, 0.02, 0.01, -0.03).finished());
  PoseGraph graph;
  for (int64_t i = 0; i < 5; ++i) {
    graph.AddPose(i, i == 0 ? Eigen::Isometry3d::Identity() : nudge * graph.Pose(i - 1) * step);
    graph.AddPose(10 + i, i == 0 ? Translation(0.0, 5.0) : graph.Pose(9 + i) * step * nudge);
  }
  // Odometry to 1 cm / 0.6 deg: a loop 6 m off cannot bend it.
  for (int64_t i = 0; i < 4; ++i) {
    graph.AddEdge(MakeEdge(i, i + 1, step, 1e4 * Matrix6d::Identity()));
    graph.AddEdge(MakeEdge(10 + i, 11 + i, step, 1e4 * Matrix6d::Identity()));
  }
  const size_t false_loop = graph.AddEdge(
      MakeEdge(10, 14, Translation(-2.0), Matrix6d::Identity(), LinkType::kLoopClosure));
  std::vector<Eigen::Isometry3d> second;
  for (int64_t i = 10; i < 15; ++i) second.push_back(graph.Pose(i));

  const PoseGraphSummary summary = graph.OptimizeAround(3);
  EXPECT_TRUE(summary.converged);
  EXPECT_TRUE(summary.rejected_edges.empty());
  for (int64_t i = 1; i < 5; ++i) {
    EXPECT_TRUE(graph.Pose(i).isApprox(graph.Pose(i - 1) * step, 1e-6)) << i;
  }
  for (int64_t i = 10; i < 15; ++i) {
    EXPECT_TRUE(graph.Pose(i).isApprox(second[static_cast<size_t>(i - 10)], 0.0)) << i;
  }
  EXPECT_TRUE(graph.EdgeActive(false_loop));

  // Around a pose of the second chain, the false loop is found and switched off.
  const PoseGraphSummary around_second = graph.OptimizeAround(12);
  ASSERT_EQ(around_second.rejected_edges.size(), 1u);
  EXPECT_EQ(around_second.rejected_edges[0], false_loop);
  EXPECT_TRUE(graph.Pose(14).isApprox(graph.Pose(10) * step * step * step * step, 1e-6));
  EXPECT_THROW(graph.OptimizeAround(77), Error);
}

// Two laps of 40 poses, every loop consistent and the map optimised: what a mapper holds when
// the next loop of a revisit arrives.
synthetic::Scene SettledTwoLaps() {
  synthetic::CircleOptions options;
  options.laps = 2;
  options.loop_every = 4;
  options.odometry_sigma_m = 0.005;
  options.odometry_sigma_rad = 0.002;
  synthetic::Scene scene = synthetic::MakeCircleScene(options);
  scene.graph.Optimize();
  return scene;
}

PoseGraphEdge LoopAsTheMapHasIt(const PoseGraph& graph, int64_t from, int64_t to,
                                const Eigen::Isometry3d& error = Eigen::Isometry3d::Identity()) {
  return MakeEdge(from, to, error * graph.Pose(from).inverse() * graph.Pose(to),
                  Information(0.003, 0.001), LinkType::kLoopClosure);
}

TEST(PoseGraph, OptimizeNearMovesOnlyThePosesNearALoopThatFitsTheMap) {
  synthetic::Scene scene = SettledTwoLaps();
  PoseGraph& graph = scene.graph;
  // A loop 2 mm and 0.05 degrees from where the map has it: it fits.
  const size_t loop = graph.AddEdge(LoopAsTheMapHasIt(
      graph, 30, 70, ExpSe3((Vector6d() << 0.002, 0.0, 0.0, 0.0, 0.0, 0.001).finished())));
  const PoseGraph before = graph;
  const PoseGraphSummary summary = graph.OptimizeNear(loop, 3, 1.0);
  EXPECT_TRUE(summary.local);
  EXPECT_TRUE(summary.rejected_edges.empty());
  ASSERT_FALSE(summary.moved_poses.empty());
  // Within 3 links of 30 or 70: along the laps, and across the loops every 4th pose makes.
  for (int64_t id : summary.moved_poses) {
    const int64_t lap_position = id % 40;
    EXPECT_TRUE(std::abs(lap_position - 30) <= 3) << id;
  }
  int unmoved = 0;
  for (int64_t id = 0; id < 80; ++id) {
    if (std::find(summary.moved_poses.begin(), summary.moved_poses.end(), id) !=
        summary.moved_poses.end()) {
      continue;
    }
    EXPECT_TRUE(graph.Pose(id).isApprox(before.Pose(id), 0.0)) << id;
    ++unmoved;
  }
  EXPECT_GT(unmoved, 60);
  // Close to what the whole graph would do: within a millimetre.
  PoseGraph whole = before;
  whole.Optimize();
  for (int64_t id = 0; id < 80; ++id) {
    EXPECT_LT((graph.Pose(id).translation() - whole.Pose(id).translation()).norm(), 1e-3) << id;
  }
}

TEST(PoseGraph, OptimizeNearBendsTheWholePartForALoopThatDoesNotFit) {
  // One lap dead-reckoned with drift, then the loop onto the start: the correction must spread
  // over the whole lap. A window around the loop's ends could take it with a small rise on each
  // of its links and leave the middle of the lap where it was (ATE 14 cm instead of 5), but the
  // loop closes no cycle inside it: the whole lap is optimised.
  synthetic::CircleOptions options;
  options.close_last_onto_first = true;
  synthetic::Scene scene = synthetic::MakeCircleScene(options);
  const double rmse_before = PositionRmse(scene.graph, scene.truth);
  PoseGraph whole = scene.graph;
  whole.OptimizeAround(39);
  const PoseGraphSummary summary = scene.graph.OptimizeNear(scene.loop_edges[0], 3, 1.0);
  EXPECT_FALSE(summary.local);
  EXPECT_EQ(summary.moved_poses.size(), 39u) << "all but the gauge";
  for (int64_t id = 0; id < 40; ++id) {
    EXPECT_TRUE(scene.graph.Pose(id).isApprox(whole.Pose(id), 1e-9)) << id;
  }
  EXPECT_LT(PositionRmse(scene.graph, scene.truth), 0.5 * rmse_before);  // 14 cm -> 5 cm
}

TEST(PoseGraph, OptimizeNearLeavesAFalseLoopToTheWholePartWhichSwitchesItOff) {
  synthetic::Scene scene = SettledTwoLaps();
  PoseGraph& graph = scene.graph;
  // 30 cm and 5 degrees off: no window makes it fit without breaking the loops around it.
  const size_t false_loop = graph.AddEdge(LoopAsTheMapHasIt(
      graph, 30, 70, ExpSe3((Vector6d() << 0.3, 0.0, 0.0, 0.0, 0.0, 0.09).finished())));
  const PoseGraph before = graph;
  const PoseGraphSummary summary = graph.OptimizeNear(false_loop, 3, 1.0);
  EXPECT_FALSE(summary.local);
  ASSERT_EQ(summary.rejected_edges.size(), 1u);
  EXPECT_EQ(summary.rejected_edges[0], false_loop);
  EXPECT_FALSE(graph.EdgeActive(false_loop));
  for (int64_t id = 0; id < 80; ++id) {
    EXPECT_LT((graph.Pose(id).translation() - before.Pose(id).translation()).norm(), 1e-3) << id;
  }
}

// The map's first keyframe is fixed (it defines the map's frame): a window that reaches it must
// leave it where it is. Unfixed, the same window moves it with the correction.
TEST(PoseGraph, OptimizeNearHoldsAFixedPoseInsideItsWindow) {
  for (const bool fixed : {false, true}) {
    synthetic::Scene scene = SettledTwoLaps();
    PoseGraph& graph = scene.graph;
    graph.SetFixed(0, fixed);
    // A loop near the start, 3 cm and 0.3 degrees from where the map has it.
    const size_t loop = graph.AddEdge(LoopAsTheMapHasIt(
        graph, 1, 41, ExpSe3((Vector6d() << 0.03, 0.0, 0.0, 0.0, 0.0, 0.005).finished())));
    const Eigen::Isometry3d first = graph.Pose(0);
    const PoseGraphSummary summary = graph.OptimizeNear(loop, 3, 1.0);
    ASSERT_TRUE(summary.converged);
    const double moved = (graph.Pose(0).translation() - first.translation()).norm();
    if (fixed) {
      EXPECT_TRUE(graph.Pose(0).isApprox(first, 0.0));
    } else {
      EXPECT_GT(moved, 1e-4) << "the window did not reach pose 0: the test proves nothing";
    }
  }
}

TEST(PoseGraph, OptimizeNearRefusesBadArguments) {
  synthetic::Scene scene = SettledTwoLaps();
  const size_t edges = scene.graph.Edges().size();
  EXPECT_THROW(scene.graph.OptimizeNear(edges, 3, 1.0), Error);
  EXPECT_THROW(scene.graph.OptimizeNear(0, -1, 1.0), Error);
  EXPECT_THROW(scene.graph.OptimizeNear(0, 3, -1.0), Error);
}

TEST(PoseGraph, InvalidInputThrows) {
  PoseGraph graph;
  graph.AddPose(1, Eigen::Isometry3d::Identity());
  graph.AddPose(2, Translation(1.0));
  EXPECT_THROW(graph.AddPose(1, Translation(2.0)), Error);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_THROW(graph.AddPose(3, scaled), Error);
  EXPECT_THROW(graph.SetPose(7, Translation(1.0)), Error);
  EXPECT_THROW(graph.Pose(7), Error);
  EXPECT_THROW(graph.SetFixed(7), Error);
  EXPECT_FALSE(graph.HasPose(7));

  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 7, Translation(1.0), Matrix6d::Identity())), Error);
  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 1, Translation(1.0), Matrix6d::Identity())), Error);
  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 2, Translation(1.0), -Matrix6d::Identity())), Error);
  Matrix6d indefinite = Matrix6d::Identity();
  indefinite(4, 4) = -0.5;
  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 2, Translation(1.0), indefinite)), Error);
  Matrix6d asymmetric = Matrix6d::Identity();
  asymmetric(0, 3) = 0.5;
  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 2, Translation(1.0), asymmetric)), Error);
  Matrix6d not_finite = Matrix6d::Identity();
  not_finite(2, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(graph.AddEdge(MakeEdge(1, 2, Translation(1.0), not_finite)), Error);
  EXPECT_TRUE(graph.Edges().empty());
  // Semi-definite is fine (a measurement of translation only).
  Matrix6d translation_only = Matrix6d::Zero();
  translation_only.topLeftCorner<3, 3>().setIdentity();
  EXPECT_EQ(graph.AddEdge(MakeEdge(1, 2, Translation(1.0), translation_only)), 0u);
  EXPECT_THROW(graph.EdgeActive(1), Error);

  PoseGraphOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error));
  options.max_iterations = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THROW(graph.Optimize(options), InvalidArgument);
  options = PoseGraphOptions();
  options.loop_loss_scale = -1.0;
  EXPECT_THROW(graph.Optimize(options), InvalidArgument);
  options = PoseGraphOptions();
  options.max_loop_chi2 = 0.0;
  EXPECT_THROW(graph.Optimize(options), InvalidArgument);
}

// Covariance of the position of `to` (its origin moved by the relative pose's error r = (t, w)
// applied on the left: t + w x p) from PathCovariance's covariance of r.
Eigen::Matrix3d PositionCovariance(const Matrix6d& covariance, const Eigen::Vector3d& p) {
  Eigen::Matrix<double, 3, 6> jacobian;
  jacobian << Eigen::Matrix3d::Identity(), -Skew(p);
  return jacobian * covariance * jacobian.transpose();
}

// Five poses 1 m apart along x, joined by four odometry edges of sigma 0.1 m / 0.01 rad. An
// edge's rotation error turns about the edge's `from` pose and swings the far end sideways by its
// distance from there: the end's y and z variance is 4 x 0.1^2 + 0.01^2 x (4^2 + 3^2 + 2^2 + 1^2),
// along the chain 4 x 0.1^2 only. Seen from the other end the levers are 3, 2, 1 and 0 m.
TEST(PoseGraph, PathCovarianceChainsTheEdgesWithTheirLevers) {
  PoseGraph graph;
  for (int i = 0; i < 5; ++i) graph.AddPose(i, Translation(i));
  for (int i = 0; i < 4; ++i)
    graph.AddEdge(MakeEdge(i, i + 1, Translation(1.0), Matrix6d::Identity()));
  const auto covariance = [](size_t) { return DiagonalCovariance(0.1, 0.01); };
  const std::optional<Matrix6d> forward = graph.PathCovariance(0, 4, covariance, 1.0);
  ASSERT_TRUE(forward);
  const Eigen::Matrix3d end = PositionCovariance(*forward, Eigen::Vector3d(4.0, 0.0, 0.0));
  EXPECT_NEAR(end(0, 0), 0.04, 1e-12);
  EXPECT_NEAR(end(1, 1), 0.043, 1e-12);
  EXPECT_NEAR(end(2, 2), 0.043, 1e-12);
  EXPECT_NEAR((forward->bottomRightCorner<3, 3>().trace()), 3 * 4 * 1e-4, 1e-12);
  const std::optional<Matrix6d> backward = graph.PathCovariance(4, 0, covariance, 1.0);
  ASSERT_TRUE(backward);
  const Eigen::Matrix3d start = PositionCovariance(*backward, Eigen::Vector3d(-4.0, 0.0, 0.0));
  EXPECT_NEAR(start(0, 0), 0.04, 1e-12);
  EXPECT_NEAR(start(1, 1), 0.0414, 1e-12);
  EXPECT_NEAR(graph.PathCovariance(2, 2, covariance, 1.0)->norm(), 0.0, 0.0);
}

// A firm loop edge from 0 to 4 is the path taken; switched off, the chain again; a pose no
// active edge reaches has no path.
TEST(PoseGraph, PathCovarianceTakesTheFirmestActivePath) {
  PoseGraph graph;
  for (int i = 0; i < 6; ++i) graph.AddPose(i, Translation(i));
  for (int i = 0; i < 4; ++i)
    graph.AddEdge(MakeEdge(i, i + 1, Translation(1.0), Matrix6d::Identity()));
  const size_t loop =
      graph.AddEdge(MakeEdge(0, 4, Translation(4.0), Matrix6d::Identity(), LinkType::kLoopClosure));
  const auto covariance = [&](size_t edge) {
    return edge == loop ? DiagonalCovariance(0.01, 0.001) : DiagonalCovariance(0.1, 0.01);
  };
  EXPECT_NEAR(graph.PathCovariance(0, 4, covariance, 1.0)->trace(), 3e-4 + 3e-6, 1e-12);
  // Through the loop and back one edge: 4 -> 3 costs one chain edge, not three.
  const Eigen::Matrix3d three =
      PositionCovariance(*graph.PathCovariance(0, 3, covariance, 1.0), Eigen::Vector3d(3, 0, 0));
  EXPECT_NEAR(three(0, 0), 1e-4 + 1e-2, 1e-12);
  graph.SetEdgeActive(loop, false);
  EXPECT_NEAR(PositionCovariance(*graph.PathCovariance(0, 4, covariance, 1.0),
                                 Eigen::Vector3d(4.0, 0.0, 0.0))
                  .trace(),
              3 * 0.04 + 2 * 0.003, 1e-12);
  EXPECT_FALSE(graph.PathCovariance(0, 5, covariance, 1.0));
  EXPECT_THROW(graph.PathCovariance(0, 9, covariance, 1.0), Error);
  EXPECT_THROW(graph.PathCovariance(0, 4, covariance, -1.0), Error);
}

// 2,000 poses (4 laps of 500 around a 4 m circle) with 20 loops and a false one: the figures
// for the issue (pose_graph_benchmark has the steadier ones). The time is printed, not asserted.
// A bare wall's information fixes z and the two tilts only: its inverse leaves the other three
// directions free (1/ridge) and the fixed ones as they were; a full-rank matrix inverts exactly.
TEST(PoseGraph, RidgedInverseLeavesSingularDirectionsFree) {
  Matrix6d wall = Matrix6d::Zero();
  wall(2, 2) = 1e6;
  wall(3, 3) = 2e5;
  wall(4, 4) = 3e5;
  wall(2, 3) = wall(3, 2) = 1e4;
  const Matrix6d covariance = RidgedInverse(wall, 1e-9);
  ASSERT_TRUE(covariance.allFinite());
  EXPECT_TRUE(covariance.isApprox(covariance.transpose()));
  for (const int free : {0, 1, 5}) EXPECT_NEAR(covariance(free, free), 1e9, 1.0);
  const Eigen::Matrix3d fixed = wall.block<3, 3>(2, 2);
  const Eigen::Matrix3d fixed_covariance = covariance.block<3, 3>(2, 2);
  EXPECT_TRUE(fixed_covariance.isApprox(fixed.inverse(), 1e-9));

  const Matrix6d full = DiagonalCovariance(0.02, 0.01) + 1e-5 * Matrix6d::Ones();
  EXPECT_TRUE((RidgedInverse(full, 0.0) * full).isApprox(Matrix6d::Identity(), 1e-9));
}

TEST(PoseGraph, LargeGraphFigures) {
  const synthetic::CircleOptions options = synthetic::LargeCircleOptions();
  synthetic::Scene scene = synthetic::MakeCircleScene(options);
  ASSERT_EQ(scene.loop_edges.size(), 20u);
  // Place recognition confuses pose 350 (on the far side of the circle) with a view 30 cm in front
  // of pose 100.
  const size_t false_index = scene.graph.AddEdge(
      MakeEdge(100, 350, ExpSe3((Vector6d() << 0.05, 0.0, 0.3, 0.0, 0.09, 0.0).finished()),
               Information(options.loop_sigma_m, options.loop_sigma_rad), LinkType::kLoopClosure));
  const double before = PositionRmse(scene.graph, scene.truth);
  PoseGraphOptions pose_graph_options;
  pose_graph_options.max_solver_time_s = 10.0;  // a loaded test machine must not cut it short
  const PoseGraphSummary summary = scene.graph.Optimize(pose_graph_options);
  const double after = PositionRmse(scene.graph, scene.truth);
  std::cout << "[ figures  ] 2000 poses, 20 loops + 1 false: RMSE " << before << " m -> " << after
            << " m, " << summary.solves << " solves, " << summary.iterations << " iterations, "
            << summary.time_s * 1e3 << " ms\n";
  EXPECT_TRUE(summary.converged);
  ASSERT_EQ(summary.rejected_edges.size(), 1u);
  EXPECT_EQ(summary.rejected_edges[0], false_index);
  EXPECT_LT(after, 0.5 * before);
}

}  // namespace
}  // namespace sightmap::slam
