#include "render/mesh_renderer.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::render {
namespace {

Intrinsics TestCamera() {
  Intrinsics k;
  k.width = 320;
  k.height = 240;
  k.fx = 300;
  k.fy = 310;
  k.cx = 150.5;  // off-centre on purpose: the projection must use cx, cy
  k.cy = 125.0;
  return k;
}

// A camera at `position` looking along world +x (z up): world_from_cam's columns are the camera
// axes (x right = -y world, y down = -z world, z forward = +x world).
Eigen::Isometry3d LookingAlongX(const Eigen::Vector3d& position) {
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear().col(0) = Eigen::Vector3d(0, -1, 0);
  world_from_cam.linear().col(1) = Eigen::Vector3d(0, 0, -1);
  world_from_cam.linear().col(2) = Eigen::Vector3d(1, 0, 0);
  world_from_cam.translation() = position;
  return world_from_cam;
}

TEST(OffscreenContext, ReportsAGlVersionAndResizes) {
  OffscreenContext context(32, 16);
  EXPECT_FALSE(context.GlVersion().empty());
  EXPECT_EQ(context.width(), 32);
  context.Resize(64, 48);
  EXPECT_EQ(context.width(), 64);
  EXPECT_EQ(context.height(), 48);
  EXPECT_THROW(OffscreenContext bad(0, 10), Error);
}

// A red box in front of a camera with an arbitrary pose: its pixels are exactly where the
// intrinsics project its corners, and the read-back depth is the true camera-frame z.
TEST(MeshRenderer, BoxLandsWhereTheIntrinsicsProjectItWithTrueDepth) {
  MeshRenderer renderer;
  Material red;
  red.color_rgb = Eigen::Vector3f(1, 0, 0);
  red.unlit = true;
  const Eigen::Vector3f center(2.0f, 1.0f, 1.2f);
  const Eigen::Vector3f size(0.2f, 0.6f, 0.4f);
  renderer.AddMesh(MakeBox(center, size, 0.0f, red, 7));

  const Eigen::Isometry3d world_from_cam = LookingAlongX(Eigen::Vector3d(0, 0.9, 1.1));
  const Intrinsics k = TestCamera();
  const RenderedView view = renderer.Render(k, world_from_cam);
  ASSERT_EQ(view.color.type(), CV_8UC3);
  ASSERT_EQ(view.depth.type(), CV_32F);

  // The front face (x = 1.9) spans world y in [0.7, 1.3], z in [1.0, 1.4].
  const Eigen::Isometry3d cam_from_world = world_from_cam.inverse();
  const Eigen::Vector2d top_left =
      k.Project(cam_from_world * Eigen::Vector3d(1.9, 1.3, 1.4));  // +y world is image left
  const Eigen::Vector2d bottom_right = k.Project(cam_from_world * Eigen::Vector3d(1.9, 0.7, 1.0));
  int red_pixels = 0;
  int misplaced = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const bool is_red = view.color.at<cv::Vec3b>(v, u)[2] > 200;
      const bool inside =
          u > top_left.x() && u < bottom_right.x() && v > top_left.y() && v < bottom_right.y();
      const bool near_edge = std::abs(u - top_left.x()) < 1 || std::abs(u - bottom_right.x()) < 1 ||
                             std::abs(v - top_left.y()) < 1 || std::abs(v - bottom_right.y()) < 1;
      if (near_edge) continue;
      red_pixels += is_red;
      misplaced += is_red != inside;
      if (inside) {
        EXPECT_NEAR(view.depth.at<float>(v, u), 1.9f, 2e-3f) << u << "," << v;
      } else {
        EXPECT_EQ(view.depth.at<float>(v, u), 0.0f) << u << "," << v;
      }
    }
  }
  const double expected_area =
      (bottom_right.x() - top_left.x()) * (bottom_right.y() - top_left.y());
  EXPECT_GT(red_pixels, 0.9 * expected_area);
  EXPECT_EQ(misplaced, 0);

  // The ID buffer: the box's id inside, 0 outside; drawing it alone gives the same footprint.
  const cv::Mat ids = renderer.RenderIds(k, world_from_cam);
  const cv::Mat alone = renderer.RenderIds(k, world_from_cam, 7);
  const int cu = static_cast<int>((top_left.x() + bottom_right.x()) / 2);
  const int cv_ = static_cast<int>((top_left.y() + bottom_right.y()) / 2);
  EXPECT_EQ(ids.at<int32_t>(cv_, cu), 7);
  EXPECT_EQ(ids.at<int32_t>(0, 0), 0);
  EXPECT_EQ(cv::countNonZero(ids != alone), 0);
}

// A textured wall seen at 3 m: depth exact over the whole image, and lighting/texture vary the
// colour while the no-depth flag of a "window" is reported where the window is.
TEST(MeshRenderer, FarWallDepthAndNoDepthMask) {
  MeshRenderer renderer;
  cv::Mat texture(64, 64, CV_8UC3);
  cv::randu(texture, 0, 255);
  Material wall;
  wall.texture = renderer.AddTexture(texture);
  renderer.AddMesh(MakeBox(Eigen::Vector3f(3.05f, 0, 1.5f), Eigen::Vector3f(0.1f, 10, 3), 0, wall));
  Material glass;
  glass.no_depth = true;
  renderer.AddMesh(
      MakeBox(Eigen::Vector3f(2.99f, -0.5f, 1.5f), Eigen::Vector3f(0.02f, 0.4f, 0.4f), 0, glass));
  const Eigen::Isometry3d world_from_cam = LookingAlongX(Eigen::Vector3d(0, 0, 1.5));
  Intrinsics k = TestCamera();
  k.cx = 159.5;
  k.cy = 119.5;
  const RenderedView view = renderer.Render(k, world_from_cam);
  double max_error = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      if (view.no_depth.at<uint8_t>(v, u)) continue;
      max_error = std::max(max_error, std::abs(view.depth.at<float>(v, u) - 3.0));
    }
  }
  EXPECT_LT(max_error, 5e-3);
  // The window at world y = -0.5 is right of the centre: u = cx + fx * 0.5 / 2.99.
  const int window_u = static_cast<int>(std::lround(k.cx + k.fx * 0.5 / 2.99));
  EXPECT_EQ(view.no_depth.at<uint8_t>(120, window_u), 255);
  EXPECT_EQ(view.no_depth.at<uint8_t>(120, 40), 0);
  const double window_area = (0.4 * k.fx / 2.99) * (0.4 * k.fy / 2.99);
  EXPECT_NEAR(cv::countNonZero(view.no_depth), window_area, 0.1 * window_area);
  cv::Scalar mean, stddev;
  cv::meanStdDev(view.color, mean, stddev);
  EXPECT_GT(stddev[0], 20.0);  // the random texture shows through
}

// A stream of textures (view synthesis draws each keyframe's image once) does not pile up:
// ClearTextures drops them and every mesh, handles restart at 0, and an old handle is refused.
TEST(MeshRenderer, ClearTexturesDropsTexturesAndMeshes) {
  MeshRenderer renderer;
  cv::Mat green(8, 8, CV_8UC3, cv::Scalar(0, 255, 0));
  cv::Mat blue(8, 8, CV_8UC3, cv::Scalar(255, 0, 0));
  Material material;
  material.unlit = true;
  material.color_rgb = Eigen::Vector3f(1, 1, 1);
  EXPECT_EQ(renderer.AddTexture(green), 0);
  material.texture = renderer.AddTexture(green);
  EXPECT_EQ(material.texture, 1);
  renderer.AddMesh(MakeBox(Eigen::Vector3f(3, 0, 0), Eigen::Vector3f(0.1f, 4, 4), 0, material));
  renderer.ClearTextures();
  EXPECT_EQ(renderer.num_textures(), 0u);
  EXPECT_EQ(renderer.num_meshes(), 0u);
  EXPECT_THROW(
      renderer.AddMesh(MakeBox(Eigen::Vector3f(3, 0, 0), Eigen::Vector3f(0.1f, 4, 4), 0, material)),
      Error);
  material.texture = renderer.AddTexture(blue);
  EXPECT_EQ(material.texture, 0);
  renderer.AddMesh(MakeBox(Eigen::Vector3f(3, 0, 0), Eigen::Vector3f(0.1f, 4, 4), 0, material));
  const RenderedView view = renderer.Render(TestCamera(), LookingAlongX(Eigen::Vector3d::Zero()));
  const cv::Vec3b centre = view.color.at<cv::Vec3b>(120, 160);
  EXPECT_GT(centre[0], 200);  // the new texture, blue
  EXPECT_LT(centre[1], 50);
}

}  // namespace
}  // namespace sightmap::render
