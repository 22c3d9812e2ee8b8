#include "core/rotation.h"

#include <cmath>

namespace sightmap {

double RotationAngleDeg(const Eigen::Matrix3d& rotation) {
  return RadToDeg(Eigen::AngleAxisd(rotation).angle());
}

double RotationAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return RotationAngleDeg(Eigen::Matrix3d(a.transpose() * b));
}

double RotationAngleDeg(const Eigen::Isometry3d& motion) {
  return RotationAngleDeg(motion.linear());
}

Eigen::Matrix<double, 6, 6> AdjointSe3(const Eigen::Isometry3d& motion) {
  Eigen::Matrix<double, 6, 6> adjoint = Eigen::Matrix<double, 6, 6>::Zero();
  adjoint.topLeftCorner<3, 3>() = motion.linear();
  adjoint.topRightCorner<3, 3>() = Skew(motion.translation()) * motion.linear();
  adjoint.bottomRightCorner<3, 3>() = motion.linear();
  return adjoint;
}

bool MotionWithin(const Eigen::Isometry3d& motion, double max_m, double max_deg) {
  return motion.translation().norm() <= max_m && RotationAngleDeg(motion) <= max_deg;
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Isometry3d ExpSe3(const Eigen::Matrix<double, 6, 1>& delta) {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d rotation = delta.tail<3>();
  if (rotation.norm() > 0.0) {
    motion.linear() = Eigen::AngleAxisd(rotation.norm(), rotation.normalized()).matrix();
  }
  motion.translation() = delta.head<3>();
  return motion;
}

Eigen::Matrix<double, 6, 1> LogSe3(const Eigen::Isometry3d& motion) {
  const Eigen::AngleAxisd turn(motion.linear());
  Eigen::Matrix<double, 6, 1> delta;
  delta << motion.translation(), turn.angle() * turn.axis();
  return delta;
}

Eigen::Isometry3d Orthonormalised(const Eigen::Isometry3d& pose) {
  Eigen::Isometry3d rigid = Eigen::Isometry3d::Identity();
  rigid.linear() = Eigen::Quaterniond(pose.linear()).normalized().toRotationMatrix();
  rigid.translation() = pose.translation();
  return rigid;
}

void FloorAxes(const Eigen::Vector3d& up, Eigen::Vector3d* e1, Eigen::Vector3d* e2) {
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(up) * up;
  if (x.norm() < 1e-3) x = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(up) * up;
  *e1 = x.normalized();
  *e2 = up.cross(*e1);
}

double FloorBearingDeg(const Eigen::Vector3d& offset, const Eigen::Vector3d& e1,
                       const Eigen::Vector3d& e2) {
  const double deg = RadToDeg(std::atan2(offset.dot(e2), offset.dot(e1)));
  return deg < 0.0 ? deg + 360.0 : deg;
}

}  // namespace sightmap
