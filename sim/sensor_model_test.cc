#include "sim/sensor_model.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "render/mesh_renderer.h"
#include "sim/simulator.h"
#include "sim/trajectory.h"

namespace sightmap::sim {
namespace {

// A camera at the origin looking along world +x with a wall (and optionally a post) ahead.
struct WallRig {
  render::MeshRenderer renderer;
  Intrinsics k = KinectIntrinsics();
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();

  explicit WallRig(double wall_distance_m) {
    render::Material plain;
    renderer.AddMesh(
        render::MakeBox(Eigen::Vector3f(static_cast<float>(wall_distance_m) + 0.05f, 0, 0),
                        Eigen::Vector3f(0.1f, 20, 20), 0, plain));
    world_from_cam.linear() = WorldFromCamRotation(0.0, 0.0, 0.0);
  }
};

// The measured depth noise on a flat wall facing the camera matches sigma(z) = 1.425e-3 z^2
// within 20% at 1, 2 and 3 m (quantisation included, as the model defines it).
TEST(SensorModel, FlatWallNoiseMatchesTheModelAt1To3Metres) {
  const DepthSensorOptions options;
  for (const double z : {1.0, 2.0, 3.0}) {
    WallRig rig(z);
    const render::RenderedView view = rig.renderer.Render(rig.k, rig.world_from_cam);
    const cv::Mat depth = SimulateDepth(view.depth, view.no_depth, rig.k, options, 42);
    double sum = 0, sum2 = 0;
    int n = 0;
    for (int v = 100; v < 380; ++v) {
      for (int u = 100; u < 540; ++u) {
        const uint16_t mm = depth.at<uint16_t>(v, u);
        if (mm == 0) continue;
        const double error = mm * 1e-3 - z;
        sum += error;
        sum2 += error * error;
        ++n;
      }
    }
    ASSERT_GT(n, 100000) << "a wall facing the camera must be measured almost everywhere";
    const double mean = sum / n;
    const double stddev = std::sqrt(sum2 / n - mean * mean);
    const double model = options.DepthStdDev(z);
    std::printf("flat wall at %.0f m: measured sigma %.2f mm, model %.2f mm, bias %.2f mm\n", z,
                stddev * 1e3, model * 1e3, mean * 1e3);
    EXPECT_NEAR(stddev, model, 0.2 * model) << "at " << z << " m";
    EXPECT_LT(std::abs(mean), 0.3 * model) << "at " << z << " m";
  }
}

// Range limits, the invalid border, and no depth on no-return surfaces.
TEST(SensorModel, RangeBorderAndNoReturnSurfaces) {
  const DepthSensorOptions options;
  cv::Mat ideal(480, 640, CV_32F, cv::Scalar(2.0f));
  ideal(cv::Rect(300, 0, 40, 480)) = 0.3f;  // too close
  ideal(cv::Rect(400, 0, 40, 480)) = 9.0f;  // too far
  ideal(cv::Rect(500, 0, 40, 480)) = 7.0f;  // far, but within a PrimeSense sensor's range
  cv::Mat mask(480, 640, CV_8U, cv::Scalar(0));
  mask(cv::Rect(100, 100, 50, 50)) = 255;  // glass
  const cv::Mat depth = SimulateDepth(ideal, mask, KinectIntrinsics(), options, 1);
  EXPECT_EQ(cv::countNonZero(depth(cv::Rect(305, 10, 30, 460))), 0);
  EXPECT_EQ(cv::countNonZero(depth(cv::Rect(405, 10, 30, 460))), 0);
  // (Its right edge lies in the shadow of the 2 m wall beside it: 525 * 0.075 * (1/2 - 1/7) =
  // 14 px.)
  EXPECT_GT(cv::countNonZero(depth(cv::Rect(502, 30, 20, 400))), 20 * 400 * 9 / 10);
  EXPECT_EQ(cv::countNonZero(depth(cv::Rect(102, 102, 46, 46))), 0);
  EXPECT_EQ(cv::countNonZero(depth.colRange(0, options.border_left_px)), 0);
  EXPECT_EQ(cv::countNonZero(depth.rowRange(0, options.border_top_px)), 0);
  // Left of the close strip lies its projector shadow (u 189-300); measure away from it.
  EXPECT_GT(cv::countNonZero(depth(cv::Rect(20, 300, 50, 50))), 2400);
}

// A post 1 m in front of a wall at 3 m: the emitter 7.5 cm to the right leaves a band without
// depth left of the post, f * b * (1/1 - 1/3) = 26 px wide, and none on its right.
TEST(SensorModel, ProjectorShadowLeftOfForegroundObjects) {
  WallRig rig(3.0);
  render::Material plain;
  rig.renderer.AddMesh(
      render::MakeBox(Eigen::Vector3f(1.05f, 0, 0), Eigen::Vector3f(0.1f, 0.3f, 2.0f), 0, plain));
  const render::RenderedView view = rig.renderer.Render(rig.k, rig.world_from_cam);
  DepthSensorOptions options;
  options.discontinuity_dropout = 0.0;  // isolate the shadow
  const cv::Mat depth = SimulateDepth(view.depth, view.no_depth, rig.k, options, 3);
  // The post's front face spans u = cx +- 525 * 0.15 / 1.0.
  const int left_edge = static_cast<int>(std::ceil(319.5 - 525 * 0.15));
  const int right_edge = static_cast<int>(std::floor(319.5 + 525 * 0.15));
  const int expected = static_cast<int>(std::lround(525 * 0.075 * (1.0 - 1.0 / 3.0)));
  for (int v = 200; v < 280; v += 10) {
    int shadow = 0;
    for (int u = left_edge - 1; u > 0 && depth.at<uint16_t>(v, u) == 0; --u) ++shadow;
    EXPECT_NEAR(shadow, expected, 3) << "row " << v;
    EXPECT_GT(depth.at<uint16_t>(v, right_edge + 3), 2800) << "row " << v;
  }
  // With the emitter on the left, the shadow moves to the right side.
  options.projector_offset_m = -0.075;
  const cv::Mat mirrored = SimulateDepth(view.depth, view.no_depth, rig.k, options, 3);
  EXPECT_GT(mirrored.at<uint16_t>(240, left_edge - 5), 2800);
  EXPECT_EQ(mirrored.at<uint16_t>(240, right_edge + 5), 0);
}

// Surfaces seen at grazing incidence lose their depth: the floor far ahead of a low camera.
TEST(SensorModel, GrazingAnglesDropOut) {
  render::MeshRenderer renderer;
  render::Material plain;
  renderer.AddMesh(
      render::MakeBox(Eigen::Vector3f(5, 0, -0.05f), Eigen::Vector3f(20, 20, 0.1f), 0, plain));
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear() = WorldFromCamRotation(0.0, 0.0, 0.0);
  world_from_cam.translation() = Eigen::Vector3d(0, 0, 0.3);
  const Intrinsics k = KinectIntrinsics();
  const render::RenderedView view = renderer.Render(k, world_from_cam);
  const cv::Mat depth = SimulateDepth(view.depth, view.no_depth, k, DepthSensorOptions(), 5);
  // Row v sees the floor at z = 0.3 * fy / (v - cy); incidence 90 deg - atan(0.3 / z).
  // Rows near the horizon (incidence > 84 deg, z > 2.85 m) have nothing; rows at z ~0.9 m
  // (incidence ~72 deg) keep most.
  const int grazing_row = static_cast<int>(239.5 + 0.3 * 525 / 3.5);
  const int steep_row = static_cast<int>(239.5 + 0.3 * 525 / 0.9);
  EXPECT_EQ(cv::countNonZero(depth.row(grazing_row)), 0);
  // Most of the row inside the invalid border.
  const DepthSensorOptions sensor;
  const int inside = 640 - sensor.border_left_px - sensor.border_right_px;
  EXPECT_GT(cv::countNonZero(depth.row(steep_row)), inside * 79 / 100);
}

TEST(SensorModel, ColourGainBlurAndNoise) {
  cv::Mat stripes(120, 160, CV_8UC3);
  for (int u = 0; u < 160; ++u) stripes.col(u).setTo(cv::Scalar::all((u / 4) % 2 ? 200 : 50));
  ColorSensorOptions options;
  options.defocus_sigma_px = 0.0;
  const cv::Mat sharp = SimulateColor(stripes, 1.0, Eigen::Vector2d::Zero(), options, 1);
  const cv::Mat blurred = SimulateColor(stripes, 1.0, Eigen::Vector2d(12, 0), options, 1);
  const cv::Mat darker = SimulateColor(stripes, 0.5, Eigen::Vector2d::Zero(), options, 1);
  cv::Scalar mean_sharp, std_sharp, mean_blur, std_blur;
  cv::meanStdDev(sharp, mean_sharp, std_sharp);
  cv::meanStdDev(blurred, mean_blur, std_blur);
  EXPECT_LT(std_blur[0], 0.5 * std_sharp[0]);  // horizontal motion smears vertical stripes
  EXPECT_NEAR(cv::mean(darker)[0], 0.5 * mean_sharp[0], 2.0);
  // Noise: the difference of two seeds has the model's sigma * sqrt(2) on a flat 100 grey.
  const cv::Mat flat(200, 200, CV_8UC3, cv::Scalar::all(100));
  cv::Mat a, b, diff;
  SimulateColor(flat, 1.0, Eigen::Vector2d::Zero(), options, 1).convertTo(a, CV_32F);
  SimulateColor(flat, 1.0, Eigen::Vector2d::Zero(), options, 2).convertTo(b, CV_32F);
  cv::Scalar mean_diff, std_diff;
  cv::meanStdDev(a - b, mean_diff, std_diff);
  const double sigma = options.read_noise + options.shot_noise * 10.0;
  EXPECT_NEAR(std_diff[0], sigma * std::sqrt(2.0), 0.15 * sigma * std::sqrt(2.0));
}

TEST(SensorModel, OptionsAreChecked) {
  DepthSensorOptions depth;
  std::string error;
  EXPECT_TRUE(depth.Check(&error));
  depth.max_depth_m = 0.2;
  EXPECT_FALSE(depth.Check(&error));
  EXPECT_THROW(SimulateDepth(cv::Mat(4, 4, CV_32F, cv::Scalar(1)),
                             cv::Mat(4, 4, CV_8U, cv::Scalar(0)), KinectIntrinsics(), depth, 1),
               InvalidArgument);
}

}  // namespace
}  // namespace sightmap::sim
