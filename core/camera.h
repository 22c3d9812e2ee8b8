// Pinhole intrinsics in pixels, and a camera pose looking at a point. Camera frame: x right,
// y down, z forward (OpenCV).
#pragma once

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

namespace sightmap {

struct Intrinsics {
  int width = 0;    // image width [px]
  int height = 0;   // image height [px]
  double fx = 0.0;  // focal lengths [px]
  double fy = 0.0;
  double cx = 0.0;  // principal point [px], pixel centres at integer coordinates
  double cy = 0.0;

  // From horizontal and vertical fields of view [rad], principal point at the image centre. A
  // non-positive vfov means "square pixels": fy = fx.
  static Intrinsics FromFieldOfView(int width, int height, double hfov_rad, double vfov_rad);

  // A pinhole camera from its focal lengths and principal point [px], for width x height images
  // (unchecked: call Check() on values that come from a user).
  static Intrinsics FromPinhole(int width, int height, double fx, double fy, double cx, double cy);

  // The same camera at another resolution (e.g. 320x240 colour mapped onto 640x480 depth).
  Intrinsics Scaled(int new_width, int new_height) const;

  // The same camera with the image flipped left-right.
  Intrinsics MirroredHorizontally() const;

  // Pixel (u, v) with depth z [m] to a point in the camera frame [m].
  Eigen::Vector3d Unproject(double u, double v, double z) const;
  // Camera-frame point [m] to pixel coordinates; the point must have z > 0.
  Eigen::Vector2d Project(const Eigen::Vector3d& cam_point) const;

  double HorizontalFieldOfView() const;  // [rad]

  bool Check(std::string* error) const;
};

// `size` scaled, aspect kept and each side at least 1 px, so that its longer side is at most
// `max_side` [px]; `size` itself when it already is (or when max_side is not positive).
cv::Size SizeAtMostOfSide(const cv::Size& size, int max_side);

// world_from_cam of a camera at `eye` looking at `target`, its image rows running down along -up.
// `up` must not be parallel to target - eye (throws).
Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& up);

}  // namespace sightmap
