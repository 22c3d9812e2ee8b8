// Where one pose lies relative to another by the measurements alone, chained along a path of
// pose-graph edges, with every rotation the building's axes fix held to them.
//
// A loop check that asks the pose graph where it puts the loop's keyframe trusts the graph's
// estimate; on a walk held together by blind motion-model links (1 Hz, a robot that turns on the
// spot), the estimate between keyframes minutes apart is off by tens of degrees and metres, and
// its covariance chained along the path (PoseGraph::PathCovariance) grows with every blind
// link's rotation sigma (~15 degrees) levered over the distance still to go: a loop onto an
// identical room 10 m away then fits. The building's axes bound that rotation error: a keyframe
// whose depth shows them (a RotationPrior) has its rotation relative to another such keyframe
// known up to the 24 ways of naming the axes, to about a degree, whatever lies between. Chaining
// the path's measured motions and replacing each such rotation by the naming nearest the chained
// one keeps a blind link's rotation error from reaching past the next keyframe that sees the
// axes; the translation error is then the links' own translation errors, plus their rotation
// errors levered only over the stretch to the next such keyframe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>

#include "slam/pose_graph.h"

namespace sightmap::slam {

struct AxesChainOptions {
  // A chained rotation is held to the axes' nearest naming only when within this of it: farther,
  // the chain has drifted too far to tell which naming is meant [deg].
  double max_snap_deg = 20.0;
  // Nor when the chain's rotation error since the last pose held may have grown past this (its
  // largest sigma): a few blind links that each err 15 degrees add up to the next naming (the
  // 1 Hz robot turning on the spot through three blind seconds, 27 degrees each; held at every
  // pose with a prior, right loops scored chi-square 2,000-10,000) [deg].
  double max_drift_sigma_deg = 28.0;
  // Added to the two priors' sigmas when a rotation is held to the axes: a Manhattan fit's error
  // is not the prior's sigma alone (walls not quite square, a fit on few normals) [deg].
  double snap_sigma_deg = 1.0;

  bool Check(std::string* error = nullptr) const;
};
void to_json(nlohmann::json& json, const AxesChainOptions& options);
void from_json(const nlohmann::json& json, AxesChainOptions& options);

struct AxesChain {
  Eigen::Isometry3d to_in_from = Eigen::Isometry3d::Identity();
  // Of the error (translation, left rotation) of to_in_from, in `from`'s frame:
  // true = Exp(r) * to_in_from, as a pose-graph edge's error.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  int held_to_axes = 0;  // poses on the path (after the first with a prior) held to the axes
};

// Chains the measurements of `path` (edge indices into graph.Edges(), in order, the first
// touching `from`; PoseGraph::FirmestPath) from `from`. `edge_covariance(index)` is each edge's
// covariance in its parameterisation. Every pose on the path with a rotation prior after the
// first one met (`from` itself when it has one) is held to the nearest naming of the axes
// relative to that first one, when within options.max_snap_deg. Throws when the path does not
// chain from `from` or options fail Check.
AxesChain ChainAlongAxes(
    const PoseGraph& graph, int64_t from, const std::vector<size_t>& path,
    const std::function<Eigen::Matrix<double, 6, 6>(size_t edge)>& edge_covariance,
    const AxesChainOptions& options = AxesChainOptions());

}  // namespace sightmap::slam
