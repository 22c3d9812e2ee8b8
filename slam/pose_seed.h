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

}  // namespace sightmap::slam
