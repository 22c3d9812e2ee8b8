#include "slam/axes_path.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "slam/manhattan_frame.h"

namespace sightmap::slam {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;

// The error state chained along the path, in `from`'s frame: the translation's error, the current
// pose's rotation error and the rotation error of the first pose with a prior (the axes' anchor).
constexpr int kTranslation = 0;
constexpr int kRotation = 3;
constexpr int kAnchor = 6;

// Copies the error of rotation block `source` over block `target` (both its variance and its
// correlations): the two are then the same random variable.
void CopyRotationError(int source, int target, Matrix9d* covariance) {
  Matrix9d& p = *covariance;
  p.block<9, 3>(0, target) = p.block<9, 3>(0, source);
  p.block<3, 9>(target, 0) = p.block<3, 9>(source, 0);
  p.block<3, 3>(target, target) = p.block<3, 3>(source, source);
}

}  // namespace

bool AxesChainOptions::Check(std::string* error) const {
  if (!(max_snap_deg > 0.0 && max_snap_deg < 45.0) || !(snap_sigma_deg >= 0.0) ||
      !std::isfinite(snap_sigma_deg) || !(max_drift_sigma_deg > 0.0) ||
      !std::isfinite(max_drift_sigma_deg)) {
    if (error != nullptr) {
      *error =
          "max_snap_deg must lie in (0, 45), snap_sigma_deg be finite and >= 0 and "
          "max_drift_sigma_deg finite and > 0";
    }
    return false;
  }
  return true;
}

AxesChain ChainAlongAxes(const PoseGraph& graph, int64_t from, const std::vector<size_t>& path,
                         const std::function<Matrix6d(size_t edge)>& edge_covariance,
                         const AxesChainOptions& options) {
  std::string error;
  SIGHTMAP_CHECK(options.Check(&error), "AxesChainOptions: " << error);
  SIGHTMAP_CHECK(graph.HasPose(from), "ChainAlongAxes from unknown pose " << from);
  const double max_snap_rad = DegToRad(options.max_snap_deg);
  const double max_drift_rad = DegToRad(options.max_drift_sigma_deg);
  const double snap_variance = DegToRad(options.snap_sigma_deg) * DegToRad(options.snap_sigma_deg);

  AxesChain chain;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // of the current pose, in from's frame
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Matrix9d covariance = Matrix9d::Zero();
  const RotationPrior* anchor = graph.RotationPriorOf(from);
  Eigen::Matrix3d anchor_rotation = Eigen::Matrix3d::Identity();
  int64_t current = from;
  for (const size_t index : path) {
    SIGHTMAP_CHECK(index < graph.Edges().size(), "edge index " << index << " is out of range");
    const PoseGraphEdge& edge = graph.Edges()[index];
    SIGHTMAP_CHECK(edge.from == current || edge.to == current,
                   "edge " << index << " does not touch pose " << current << " of the path");
    const bool forward = edge.from == current;
    // The motion to the next pose in the current one's frame, and its error's covariance there.
    const Eigen::Isometry3d motion = forward ? edge.to_in_from : edge.to_in_from.inverse();
    Matrix6d motion_covariance = edge_covariance(index);
    if (!forward) {
      const Matrix6d adjoint = AdjointSe3(motion);
      motion_covariance = adjoint * motion_covariance * adjoint.transpose();
    }
    // position += R t: its error gains the current rotation's error levered over R t, and the
    // motion's own error, turned into from's frame (its rotation error levered over t).
    const Eigen::Vector3d step = rotation * motion.translation();
    Matrix9d propagate = Matrix9d::Identity();
    propagate.block<3, 3>(kTranslation, kRotation) = -Skew(step);
    Eigen::Matrix<double, 9, 6> noise = Eigen::Matrix<double, 9, 6>::Zero();
    noise.block<3, 3>(kTranslation, 0) = rotation;
    noise.block<3, 3>(kTranslation, 3) = -rotation * Skew(motion.translation());
    noise.block<3, 3>(kRotation, 3) = rotation;
    covariance = propagate * covariance * propagate.transpose() +
                 noise * motion_covariance * noise.transpose();
    position += step;
    rotation = rotation * motion.linear();
    current = forward ? edge.to : edge.from;

    const RotationPrior* prior = graph.RotationPriorOf(current);
    if (prior == nullptr) continue;
    if (anchor == nullptr) {
      anchor = prior;
      anchor_rotation = rotation;
      CopyRotationError(kRotation, kAnchor, &covariance);
      continue;
    }
    // The naming is a guess once the chain may have turned this pose by a good part of a quarter
    // turn since the last pose held (or the anchor).
    const Eigen::Matrix3d drift =
        covariance.block<3, 3>(kRotation, kRotation) + covariance.block<3, 3>(kAnchor, kAnchor) -
        covariance.block<3, 3>(kRotation, kAnchor) - covariance.block<3, 3>(kAnchor, kRotation);
    const double drift_sigma = std::sqrt(
        std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(drift, Eigen::EigenvaluesOnly)
                          .eigenvalues()
                          .maxCoeff()));
    if (drift_sigma > max_drift_rad) continue;
    // The anchor sees the axes as A, this pose as C: this pose in the anchor's frame turns by
    // A S C^T for one of the namings S.
    const auto [nearest, nearest_angle] = NearestManhattanRotation(
        anchor_rotation * anchor->cam_from_axes, prior->cam_from_axes, rotation);
    if (nearest_angle >= max_snap_rad) continue;
    rotation = nearest;
    CopyRotationError(kAnchor, kRotation, &covariance);
    const double variance =
        anchor->sigma_rad * anchor->sigma_rad + prior->sigma_rad * prior->sigma_rad + snap_variance;
    covariance.block<3, 3>(kRotation, kRotation) += variance * Eigen::Matrix3d::Identity();
    ++chain.held_to_axes;
  }
  SIGHTMAP_CHECK(path.empty() || graph.HasPose(current), "the path ends at an unknown pose");
  chain.to_in_from.linear() = rotation;
  chain.to_in_from.translation() = position;
  const Matrix6d head = covariance.topLeftCorner<6, 6>();
  chain.covariance = 0.5 * (head + head.transpose());
  return chain;
}

SIGHTMAP_OPTIONS_JSON(AxesChainOptions, max_snap_deg, max_drift_sigma_deg, snap_sigma_deg)

}  // namespace sightmap::slam
