// Depth images of a few infinite planes, for the tests of what depth shows of the building's axes
// (manhattan_frame_test, wall_ties_test).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/rotation.h"

namespace sightmap::testing {

inline const Intrinsics kPlaneCamera =
    Intrinsics::FromPinhole(640, 480, 570.0, 570.0, 319.5, 239.5);

// A camera 1.5 m above the floor at the origin, looking along heading `yaw_deg` (from the
// world's x towards y, z up) and `pitch_deg` below the horizon; OpenCV axes (x right, y down).
inline Eigen::Matrix3d WorldFromCam(double yaw_deg, double pitch_deg) {
  const double yaw = DegToRad(yaw_deg), pitch = DegToRad(pitch_deg);
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                                -std::sin(pitch));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Matrix3d world_from_cam;
  world_from_cam.col(0) = right;
  world_from_cam.col(1) = forward.cross(right);
  world_from_cam.col(2) = forward;
  return world_from_cam;
}

// The depth [mm] that camera (at `position`) sees of `planes` (a point p on a plane: normal . p =
// offset), the nearest plane in front of each pixel; 0 where none is.
inline cv::Mat RenderPlanes(const Eigen::Matrix3d& world_from_cam,
                            const std::vector<std::pair<Eigen::Vector3d, double>>& planes,
                            const Eigen::Vector3d& position = Eigen::Vector3d(0.0, 0.0, 1.5)) {
  cv::Mat depth(kPlaneCamera.height, kPlaneCamera.width, CV_16UC1, cv::Scalar(0));
  for (int v = 0; v < kPlaneCamera.height; ++v) {
    for (int u = 0; u < kPlaneCamera.width; ++u) {
      const Eigen::Vector3d ray_cam = kPlaneCamera.Unproject(u, v, 1.0);  // z = 1: t is the depth
      const Eigen::Vector3d ray = world_from_cam * ray_cam;
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto& [normal, offset] : planes) {
        const double along = normal.dot(ray);
        if (std::abs(along) < 1e-9) continue;
        const double t = (offset - normal.dot(position)) / along;
        if (t > 0.0) nearest = std::min(nearest, t);
      }
      if (std::isfinite(nearest)) {
        depth.at<uint16_t>(v, u) = static_cast<uint16_t>(std::lround(nearest * 1000.0));
      }
    }
  }
  return depth;
}

}  // namespace sightmap::testing
