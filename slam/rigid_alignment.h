// Least-squares rigid alignment of corresponding 3D points (Kabsch / Umeyama without scale), the
// minimal solver inside RANSAC registration and the SE(3) alignment behind ATE.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace sightmap::slam {

// The rigid transform dst_from_src minimising sum_i w_i |dst_i - (R src_i + t)|^2. Weights are
// optional (empty = all 1). Returns false when the points are too few (< 3) or degenerate
// (collinear, or all weight on fewer than three points), leaving *dst_from_src untouched.
bool AlignRigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                const std::vector<double>& weights, Eigen::Isometry3d* dst_from_src);

}  // namespace sightmap::slam
