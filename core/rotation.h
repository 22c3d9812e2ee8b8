// How far a rotation turns, in degrees, whatever its axis: the one measure that pose errors, motion
// limits and the paper's "rotation from the retrieved keyframe" check all use; and the floor
// plane's axes for a world's up direction.
#pragma once

#include <Eigen/Geometry>

namespace sightmap {

inline constexpr double kPi = 3.14159265358979323846;

// Degrees to radians and back, as `deg * kPi / 180` and `rad * 180 / kPi` (in that order, so a
// value converted here equals the one the expression gives).
inline constexpr double DegToRad(double deg) { return deg * kPi / 180.0; }
inline constexpr double RadToDeg(double rad) { return rad * 180.0 / kPi; }

// The angle of `rotation`'s axis-angle form [deg, 0-180].
double RotationAngleDeg(const Eigen::Matrix3d& rotation);
// The angle between two orientations: of a^T b [deg, 0-180].
double RotationAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);
// The angle of a rigid motion's rotation [deg, 0-180].
double RotationAngleDeg(const Eigen::Isometry3d& motion);

// The cross-product matrix [v]x, for which [v]x w = v x w.
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// [R(w) | t] for delta = (t, w), a translation and a rotation vector (angle |w| about w / |w|):
// the small motion that the pose graph's edge errors, registration's and dense alignment's
// information, and the tracker's velocity are expressed in.
Eigen::Isometry3d ExpSe3(const Eigen::Matrix<double, 6, 1>& delta);
// The (t, w) of a rigid motion: ExpSe3's inverse for rotations below 180 degrees.
Eigen::Matrix<double, 6, 1> LogSe3(const Eigen::Isometry3d& motion);

// The adjoint of a rigid motion T = [R | p] for (t, w) errors applied on the left:
// T Exp(r) T^-1 = Exp(Ad r), Ad = [[R, [p]x R], [0, R]]. It carries an error expressed in T's
// `to` frame into its `from` frame (pose-graph path covariances, an edge run backwards).
Eigen::Matrix<double, 6, 6> AdjointSe3(const Eigen::Isometry3d& motion);

// Whether a rigid motion (a step, or the difference between two poses) moves at most max_m and
// turns at most max_deg: the bound every motion and disagreement check applies, usually a rate
// times a time plus a slack. False for a motion that is not finite.
bool MotionWithin(const Eigen::Isometry3d& motion, double max_m, double max_deg);

// The nearest rigid motion (rotation through the unit quaternion). Poses from files, float
// renderers and long chains of products are orthonormal only to a few digits; the pose graph
// wants 1e-6.
Eigen::Isometry3d Orthonormalised(const Eigen::Isometry3d& pose);

// Axes of the floor plane for a unit `up`: e1 = world x projected on the floor (world y when x is
// up), e2 = up x e1. What floor plans (the preview's top-down view, `sightmap coverage`) draw on.
void FloorAxes(const Eigen::Vector3d& up, Eigen::Vector3d* e1, Eigen::Vector3d* e2);

// The bearing of `offset` in the floor plane of axes e1, e2 (FloorAxes), in [0, 360) degrees from
// e1 towards e2; its height along up plays no part.
double FloorBearingDeg(const Eigen::Vector3d& offset, const Eigen::Vector3d& e1,
                       const Eigen::Vector3d& e2);

}  // namespace sightmap
