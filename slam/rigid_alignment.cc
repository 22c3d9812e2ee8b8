#include "slam/rigid_alignment.h"

#include <Eigen/SVD>

#include "core/check.h"

namespace sightmap::slam {

bool AlignRigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                const std::vector<double>& weights, Eigen::Isometry3d* dst_from_src) {
  SIGHTMAP_CHECK(src.size() == dst.size(),
                 "AlignRigid: " << src.size() << " source but " << dst.size() << " target points");
  SIGHTMAP_CHECK(weights.empty() || weights.size() == src.size(),
                 "AlignRigid: " << weights.size() << " weights for " << src.size() << " points");
  if (src.size() < 3) return false;
  auto weight = [&weights](size_t i) { return weights.empty() ? 1.0 : weights[i]; };

  double total = 0.0;
  Eigen::Vector3d src_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d dst_mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    total += weight(i);
    src_mean += weight(i) * src[i];
    dst_mean += weight(i) * dst[i];
  }
  if (!(total > 0.0)) return false;
  src_mean /= total;
  dst_mean /= total;

  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    covariance += weight(i) * (dst[i] - dst_mean) * (src[i] - src_mean).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  // Collinear or coincident points leave a rotation about their line undetermined: the second
  // singular value vanishes relative to the first.
  const Eigen::Vector3d singular = svd.singularValues();
  if (!(singular(0) > 0.0) || singular(1) < 1e-9 * singular(0)) return false;

  Eigen::Matrix3d sign = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) sign(2, 2) = -1.0;
  const Eigen::Matrix3d rotation = svd.matrixU() * sign * svd.matrixV().transpose();

  dst_from_src->setIdentity();
  dst_from_src->linear() = rotation;
  dst_from_src->translation() = dst_mean - rotation * src_mean;
  return true;
}

}  // namespace sightmap::slam
