// Synthetic pose graphs with a known answer, for pose_graph_test and pose_graph_benchmark: a
// camera driving laps of a circle, odometry between consecutive poses and loop closures between
// the same place on consecutive laps, both with seeded noise of known covariance.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/rotation.h"
#include "slam/pose_graph.h"

namespace sightmap::slam {
namespace synthetic {

inline Eigen::Matrix<double, 6, 6> Information(double sigma_m, double sigma_rad) {
  Eigen::Matrix<double, 6, 1> diagonal;
  diagonal << Eigen::Vector3d::Constant(1.0 / (sigma_m * sigma_m)),
      Eigen::Vector3d::Constant(1.0 / (sigma_rad * sigma_rad));
  return diagonal.asDiagonal();
}

struct CircleOptions {
  int poses_per_lap = 40;
  int laps = 1;
  double radius_m = 3.0;
  double odometry_sigma_m = 0.01;
  double odometry_sigma_rad = 0.005;
  // The odometry edges claim sigmas this many times smaller than the noise they carry.
  double odometry_overconfidence = 1.0;
  // A loop edge joins pose i and i + poses_per_lap for every loop_every-th i (0: none).
  int loop_every = 0;
  double loop_sigma_m = 0.01;
  double loop_sigma_rad = 0.005;
  // Also close the last pose onto pose 0 with an exact measurement (for a single lap) of
  // information Information(loop_sigma_m, loop_sigma_rad).
  bool close_last_onto_first = false;
  uint64_t seed = 1;
};

// The large case, shared by the test that prints its figures and the benchmark: 2,000
// poses (4 laps of 500 around a 4 m circle) with 20 loops.
inline CircleOptions LargeCircleOptions() {
  CircleOptions options;
  options.poses_per_lap = 500;
  options.laps = 4;
  options.radius_m = 4.0;
  options.odometry_sigma_m = 0.005;
  options.odometry_sigma_rad = 0.002;
  options.loop_every = 75;
  options.seed = 5;
  return options;
}

struct Scene {
  std::vector<Eigen::Isometry3d> truth;  // world_from_cam by pose id
  PoseGraph graph;  // initialised by dead reckoning along the odometry, pose 0 at its truth
  std::vector<size_t> loop_edges;
};

inline Scene MakeCircleScene(const CircleOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto noise = [&](double sigma_m, double sigma_rad) {
    Eigen::Matrix<double, 6, 1> delta;
    for (int k = 0; k < 6; ++k) delta(k) = normal(rng) * (k < 3 ? sigma_m : sigma_rad);
    return ExpSe3(delta);
  };
  Scene scene;
  const int count = options.poses_per_lap * options.laps;
  for (int i = 0; i < count; ++i) {
    const double angle = 2.0 * M_PI * i / options.poses_per_lap;
    const int lap = i / options.poses_per_lap;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() =
        Eigen::Vector3d(options.radius_m * std::cos(angle), options.radius_m * std::sin(angle),
                        0.1 * std::sin(3.0 * angle) + 0.05 * lap);
    // Looking along the direction of travel with a little roll and pitch.
    pose.linear() = (Eigen::AngleAxisd(angle + M_PI / 2, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(0.05 * std::sin(2.0 * angle), Eigen::Vector3d::UnitX()) *
                     Eigen::AngleAxisd(0.03 * std::cos(5.0 * angle), Eigen::Vector3d::UnitY()))
                        .toRotationMatrix();
    scene.truth.push_back(pose);
  }
  scene.graph.AddPose(0, scene.truth[0]);
  Eigen::Isometry3d reckoned = scene.truth[0];
  for (int i = 0; i + 1 < count; ++i) {
    PoseGraphEdge edge;
    edge.from = i;
    edge.to = i + 1;
    edge.to_in_from = noise(options.odometry_sigma_m, options.odometry_sigma_rad) *
                      scene.truth[i].inverse() * scene.truth[i + 1];
    edge.information = Information(options.odometry_sigma_m / options.odometry_overconfidence,
                                   options.odometry_sigma_rad / options.odometry_overconfidence);
    reckoned = reckoned * edge.to_in_from;
    scene.graph.AddPose(i + 1, reckoned);
    scene.graph.AddEdge(edge);
  }
  if (options.loop_every > 0) {
    for (int i = 0; i + options.poses_per_lap < count; i += options.loop_every) {
      PoseGraphEdge edge;
      edge.from = i;
      edge.to = i + options.poses_per_lap;
      edge.to_in_from = noise(options.loop_sigma_m, options.loop_sigma_rad) *
                        scene.truth[i].inverse() * scene.truth[i + options.poses_per_lap];
      edge.information = Information(options.loop_sigma_m, options.loop_sigma_rad);
      edge.type = LinkType::kLoopClosure;
      scene.loop_edges.push_back(scene.graph.AddEdge(edge));
    }
  }
  if (options.close_last_onto_first) {
    PoseGraphEdge edge;
    edge.from = count - 1;
    edge.to = 0;
    edge.to_in_from = scene.truth[count - 1].inverse() * scene.truth[0];
    edge.information = Information(options.loop_sigma_m, options.loop_sigma_rad);
    edge.type = LinkType::kLoopClosure;
    scene.loop_edges.push_back(scene.graph.AddEdge(edge));
  }
  return scene;
}

// Root mean square distance of the graph's positions from the truth.
inline double PositionRmse(const PoseGraph& graph, const std::vector<Eigen::Isometry3d>& truth) {
  double squared = 0.0;
  for (size_t i = 0; i < truth.size(); ++i) {
    squared +=
        (graph.Pose(static_cast<int64_t>(i)).translation() - truth[i].translation()).squaredNorm();
  }
  return std::sqrt(squared / truth.size());
}

}  // namespace synthetic
}  // namespace sightmap::slam
