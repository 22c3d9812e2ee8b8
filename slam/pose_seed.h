// Poses seeded from relative measurements alone, as a starting point for the pose graph's
// nonlinear solve that does not depend on where earlier solves left the poses: rotations by the
// chordal relaxation (Martinec and Pajdla, CVPR 2007; Carlone et al., ICRA 2015: "Initialization
// techniques for 3D SLAM"), then translations by linear least squares with those rotations held.
// Both are linear problems with a unique minimum, so a map that earlier solves left in a local
// minimum (a stretch turned against measurements the robust losses no longer hear) is seeded
// where the measurements put it.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace sightmap::slam {

// One relative measurement between poses by index: to_in_from = from^-1 * to.
struct SeedEdge {
  size_t from = 0;
  size_t to = 0;
  Eigen::Isometry3d to_in_from = Eigen::Isometry3d::Identity();
  // Weight of the rotation's chordal error |R_to - R_from M|_F^2 [1/rad^2]: the mean of the
  // rotation information's diagonal is the natural choice (a small rotation error w changes the
  // matrix by |w| sqrt(2) in Frobenius norm, a constant factor for every edge).
  double rotation_weight = 0.0;
  // Inverse covariance of the translation error R_from^T (t_to - t_from) - M.t [1/m^2].
  Eigen::Matrix3d translation_information = Eigen::Matrix3d::Zero();
  // A motion-model link across a blind stretch (LinkType::kPrior): it joins rigid parts of the
  // map that registered links do not.
  bool bridging = false;
};

// `initial` gives every pose's estimate, `held` the poses kept as they are (at least one in every
// group the edges join, else that group's seed is only defined up to a rigid motion and stays as
// it was). Poses no edge touches keep their estimate. Each seeded pose is also held weakly to its
// estimate (`anchor_weight`, relative to the edges' weights), so that a direction no edge
// constrains (a bare wall's slide) keeps its estimate instead of leaving the system singular.
std::vector<Eigen::Isometry3d> SeedPoses(const std::vector<Eigen::Isometry3d>& initial,
                                         const std::vector<bool>& held,
                                         const std::vector<SeedEdge>& edges,
                                         double anchor_weight = 1e-6);

// A solution whose rigid parts (poses joined by edges other than bridging ones) may sit a
// quarter turn off: a part joined to the rest only by blind links, left 45-70 degrees off by
// earlier solves, has its axes priors named a quarter turn off and held there, while the
// bridging links that say otherwise are few and under a robust loss. Parts whose bridges agree
// with them as they are count as one; from the largest outwards, each next-largest part bridged
// to those placed takes the symmetry of the building's axes (world_from_axes S
// world_from_axes^T, S one of ManhattanSymmetries) that most of those bridges ask for within
// max_deviation_rad (< 45 degrees), no turn on a tie. The part holding the first `held` pose
// keeps its place (all turn back by its turn instead). Turned parts turn about their first pose,
// and every position not `held` is then solved again with the rotations held. `turned_parts`
// (may be null) gets how many parts turned; none: the poses come back as they were.
std::vector<Eigen::Isometry3d> TurnPartsToTheirBridges(const std::vector<Eigen::Isometry3d>& poses,
                                                       const std::vector<bool>& held,
                                                       const std::vector<SeedEdge>& edges,
                                                       const Eigen::Matrix3d& world_from_axes,
                                                       double max_deviation_rad,
                                                       int* turned_parts = nullptr);

}  // namespace sightmap::slam
