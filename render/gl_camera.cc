#include "render/gl_camera.h"

namespace sightmap::render {

Eigen::Matrix4d GlEyeFromCam() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(1, 1) = -1;
  m(2, 2) = -1;
  return m;
}

Eigen::Matrix4d GlPerspective(const Intrinsics& k, double near_m, double far_m) {
  Eigen::Matrix4d p = Eigen::Matrix4d::Zero();
  p(0, 0) = 2.0 * k.fx / k.width;
  p(0, 2) = 1.0 - 2.0 * (k.cx + 0.5) / k.width;
  p(1, 1) = 2.0 * k.fy / k.height;
  p(1, 2) = 2.0 * (k.cy + 0.5) / k.height - 1.0;
  p(2, 2) = -(far_m + near_m) / (far_m - near_m);
  p(2, 3) = -2.0 * far_m * near_m / (far_m - near_m);
  p(3, 2) = -1.0;
  return p;
}

Eigen::Matrix4d GlOrthographic(const Intrinsics& k, double near_m, double far_m) {
  Eigen::Matrix4d p = Eigen::Matrix4d::Zero();
  // x_ndc = 2 (u + 0.5) / w - 1 with u = cx + fx x_cam = cx + fx x_eye.
  p(0, 0) = 2.0 * k.fx / k.width;
  p(0, 3) = 2.0 * (k.cx + 0.5) / k.width - 1.0;
  // y_ndc = 1 - 2 (v + 0.5) / h with v = cy + fy y_cam = cy - fy y_eye.
  p(1, 1) = 2.0 * k.fy / k.height;
  p(1, 3) = 1.0 - 2.0 * (k.cy + 0.5) / k.height;
  p(2, 2) = -2.0 / (far_m - near_m);
  p(2, 3) = -(far_m + near_m) / (far_m - near_m);
  p(3, 3) = 1.0;
  return p;
}

}  // namespace sightmap::render
