#include "capture/depth_registration.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/check.h"

namespace sightmap::capture {

cv::Mat RegisterDepthToColor(const cv::Mat& depth_mm, const DepthToColorModel& model) {
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1, "depth must be 16-bit millimetres");
  SIGHTMAP_CHECK(depth_mm.cols == model.depth.width && depth_mm.rows == model.depth.height,
                 "depth image is " << depth_mm.cols << "x" << depth_mm.rows
                                   << " but its intrinsics are for " << model.depth.width << "x"
                                   << model.depth.height);
  const Intrinsics& kd = model.depth;
  const Intrinsics& kc = model.color;
  cv::Mat registered(kc.height, kc.width, CV_16UC1, cv::Scalar(0));

  // Footprint of one depth pixel in the colour image, rounded up: 1 when the colour image is
  // coarser.
  const int footprint_x = std::max(1, static_cast<int>(std::ceil(kc.fx / kd.fx - 1e-6)));
  const int footprint_y = std::max(1, static_cast<int>(std::ceil(kc.fy / kd.fy - 1e-6)));

  const Eigen::Matrix3d r = model.color_from_depth.linear();
  const Eigen::Vector3d t = model.color_from_depth.translation();
  // Rays of the depth camera per column and row, so the inner loop is a few multiply-adds.
  std::vector<double> ray_x(kd.width);
  std::vector<double> ray_y(kd.height);
  for (int u = 0; u < kd.width; ++u) ray_x[u] = (u - kd.cx) / kd.fx;
  for (int v = 0; v < kd.height; ++v) ray_y[v] = (v - kd.cy) / kd.fy;

  for (int v = 0; v < kd.height; ++v) {
    const uint16_t* row = depth_mm.ptr<uint16_t>(v);
    for (int u = 0; u < kd.width; ++u) {
      const uint16_t z_mm = row[u];
      if (z_mm == 0) continue;
      const double z = z_mm * 1e-3;
      const Eigen::Vector3d p = r * Eigen::Vector3d(ray_x[u] * z, ray_y[v] * z, z) + t;
      if (p.z() <= 0.0) continue;
      // The depth pixel's footprint starts at its top-left corner (u - 0.5, v - 0.5).
      const double uc = kc.fx * p.x() / p.z() + kc.cx - 0.5 * (footprint_x - 1);
      const double vc = kc.fy * p.y() / p.z() + kc.cy - 0.5 * (footprint_y - 1);
      const int u0 = static_cast<int>(std::lround(uc));
      const int v0 = static_cast<int>(std::lround(vc));
      const double z_out_mm = std::round(p.z() * 1e3);
      if (z_out_mm < 1.0 || z_out_mm > std::numeric_limits<uint16_t>::max()) continue;
      const auto z_out = static_cast<uint16_t>(z_out_mm);
      for (int dv = 0; dv < footprint_y; ++dv) {
        const int vv = v0 + dv;
        if (vv < 0 || vv >= kc.height) continue;
        uint16_t* out = registered.ptr<uint16_t>(vv);
        for (int du = 0; du < footprint_x; ++du) {
          const int uu = u0 + du;
          if (uu < 0 || uu >= kc.width) continue;
          if (out[uu] == 0 || z_out < out[uu]) out[uu] = z_out;
        }
      }
    }
  }
  return registered;
}

Eigen::Isometry3d PrimeSenseColorFromDepth(double baseline_m) {
  Eigen::Isometry3d color_from_depth = Eigen::Isometry3d::Identity();
  // The colour camera sits at +baseline on the depth camera's x axis, so a point's colour-frame
  // coordinates are its depth-frame ones minus that offset.
  color_from_depth.translation() = Eigen::Vector3d(-baseline_m, 0.0, 0.0);
  return color_from_depth;
}

}  // namespace sightmap::capture
