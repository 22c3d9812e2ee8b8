#include "render/gl_camera.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

namespace sightmap::render {
namespace {

// Where OpenGL puts a camera point: window x, y (y up from the bottom edge) and depth in [0, 1].
Eigen::Vector3d Window(const Eigen::Matrix4d& clip_from_eye, const Intrinsics& k,
                       const Eigen::Vector3d& cam_point) {
  const Eigen::Vector4d clip = clip_from_eye * GlEyeFromCam() * cam_point.homogeneous();
  const Eigen::Vector3d ndc = clip.head<3>() / clip.w();
  return {(ndc.x() + 1.0) * 0.5 * k.width, (ndc.y() + 1.0) * 0.5 * k.height, (ndc.z() + 1.0) * 0.5};
}

// An off-centre principal point and unequal focal lengths, so that a swapped axis or sign shows.
Intrinsics Camera() { return Intrinsics::FromPinhole(640, 480, 520.0, 530.0, 310.5, 250.25); }

TEST(GlCamera, PerspectiveLandsOnThePixelCentreProjectGives) {
  const Intrinsics k = Camera();
  const Eigen::Matrix4d clip_from_eye = GlPerspective(k, 0.1, 20.0);
  for (const Eigen::Vector3d& point :
       {Eigen::Vector3d(0.3, -0.2, 1.5), Eigen::Vector3d(-2.0, 1.1, 7.0),
        Eigen::Vector3d(0.0, 0.0, 0.5)}) {
    const Eigen::Vector2d pixel = k.Project(point);
    const Eigen::Vector3d window = Window(clip_from_eye, k, point);
    EXPECT_NEAR(window.x(), pixel.x() + 0.5, 1e-9);
    EXPECT_NEAR(window.y(), k.height - pixel.y() - 0.5, 1e-9);
  }
}

TEST(GlCamera, PerspectiveDepthSpansNearToFar) {
  const Intrinsics k = Camera();
  const Eigen::Matrix4d clip_from_eye = GlPerspective(k, 0.1, 20.0);
  EXPECT_NEAR(Window(clip_from_eye, k, {0.0, 0.0, 0.1}).z(), 0.0, 1e-9);
  EXPECT_NEAR(Window(clip_from_eye, k, {0.0, 0.0, 20.0}).z(), 1.0, 1e-9);
  EXPECT_LT(Window(clip_from_eye, k, {0.0, 0.0, 2.0}).z(),
            Window(clip_from_eye, k, {0.0, 0.0, 3.0}).z());
}

TEST(GlCamera, OrthographicIgnoresDepthForThePixel) {
  const Intrinsics k = Camera();
  const Eigen::Matrix4d clip_from_eye = GlOrthographic(k, 1.0, 30.0);
  for (double z : {1.0, 4.0, 30.0}) {
    const Eigen::Vector3d window = Window(clip_from_eye, k, {0.25, -0.4, z});
    EXPECT_NEAR(window.x(), k.cx + k.fx * 0.25 + 0.5, 1e-9);
    EXPECT_NEAR(window.y(), k.height - (k.cy + k.fy * -0.4) - 0.5, 1e-9);
    EXPECT_NEAR(window.z(), (z - 1.0) / 29.0, 1e-9);
  }
}

}  // namespace
}  // namespace sightmap::render
