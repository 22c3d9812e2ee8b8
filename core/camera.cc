#include "core/camera.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"

namespace sightmap {

Intrinsics Intrinsics::FromPinhole(int width, int height, double fx, double fy, double cx,
                                   double cy) {
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = fx;
  k.fy = fy;
  k.cx = cx;
  k.cy = cy;
  return k;
}

Intrinsics Intrinsics::FromFieldOfView(int width, int height, double hfov_rad, double vfov_rad) {
  if (width <= 0 || height <= 0 || !(hfov_rad > 0.0) || !(hfov_rad < M_PI)) {
    SIGHTMAP_THROW(InvalidArgument, "cannot derive intrinsics from a "
                                        << width << "x" << height
                                        << " image with a field of view of " << hfov_rad << " rad");
  }
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (2.0 * std::tan(hfov_rad / 2.0));
  k.fy = (vfov_rad > 0.0 && vfov_rad < M_PI) ? height / (2.0 * std::tan(vfov_rad / 2.0)) : k.fx;
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  return k;
}

Intrinsics Intrinsics::Scaled(int new_width, int new_height) const {
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  Intrinsics k = *this;
  k.width = new_width;
  k.height = new_height;
  k.fx = fx * sx;
  k.fy = fy * sy;
  // Pixel centres sit at integers, so the continuous image edge is at -0.5.
  k.cx = (cx + 0.5) * sx - 0.5;
  k.cy = (cy + 0.5) * sy - 0.5;
  return k;
}

Intrinsics Intrinsics::MirroredHorizontally() const {
  Intrinsics k = *this;
  k.cx = (width - 1) - cx;
  return k;
}

Eigen::Vector3d Intrinsics::Unproject(double u, double v, double z) const {
  return {(u - cx) * z / fx, (v - cy) * z / fy, z};
}

Eigen::Vector2d Intrinsics::Project(const Eigen::Vector3d& cam_point) const {
  return {fx * cam_point.x() / cam_point.z() + cx, fy * cam_point.y() / cam_point.z() + cy};
}

double Intrinsics::HorizontalFieldOfView() const { return 2.0 * std::atan(width / (2.0 * fx)); }

namespace {
constexpr int kMaxImageSide = 100000;
}  // namespace

bool Intrinsics::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (width <= 0 || height <= 0) return fail("image size must be positive");
  if (width > kMaxImageSide || height > kMaxImageSide) {
    return fail("image sides must be at most 100000 px");
  }
  // A field of view under 0.6 degrees, or a principal point more than an image away from the
  // image, is a typo or a unit mix-up, not a camera.
  const double max_focal = 100.0 * std::max(width, height);
  if (!(fx > 0.0) || !(fy > 0.0) || !(fx <= max_focal) || !(fy <= max_focal)) {
    return fail("focal lengths must be positive and at most 100 x the image's larger side [px]");
  }
  if (!(cx >= -width && cx <= 2.0 * width) || !(cy >= -height && cy <= 2.0 * height)) {
    return fail("the principal point must lie within an image's size of the image [px]");
  }
  return true;
}

cv::Size SizeAtMostOfSide(const cv::Size& size, int max_side) {
  const int longer = std::max(size.width, size.height);
  if (max_side <= 0 || longer <= max_side) return size;
  const double scale = static_cast<double>(max_side) / longer;
  return cv::Size(std::max(1, static_cast<int>(std::lround(size.width * scale))),
                  std::max(1, static_cast<int>(std::lround(size.height * scale))));
}

Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = (-up).cross(z);
  SIGHTMAP_CHECK(x.norm() > 1e-6, "cannot look straight along the up direction");
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear().col(0) = x.normalized();
  world_from_cam.linear().col(1) = z.cross(x.normalized());
  world_from_cam.linear().col(2) = z;
  world_from_cam.translation() = eye;
  return world_from_cam;
}

}  // namespace sightmap
