#include "sim/sensor_model.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "render/mesh_renderer.h"
#include "sim/random.h"
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

// The depth model as its header defines it, a pixel at a time (Eigen for the normal, the C library
// for rounding): SimulateDepth computes it in vectorised passes and must give the same bits.
cv::Mat ReferenceDepth(const cv::Mat& depth_m, const cv::Mat& no_depth_mask, const Intrinsics& k,
                       const DepthSensorOptions& options, uint64_t seed) {
  const int w = depth_m.cols;
  const int h = depth_m.rows;
  cv::Mat keep(h, w, CV_8U, cv::Scalar(255));
  if (options.projector_offset_m != 0.0) {
    const double shift = k.fx * options.projector_offset_m;
    const bool emitter_right = options.projector_offset_m > 0.0;
    for (int v = 0; v < h; ++v) {
      double extreme = emitter_right ? std::numeric_limits<double>::infinity()
                                     : -std::numeric_limits<double>::infinity();
      for (int i = 0; i < w; ++i) {
        const int u = emitter_right ? w - 1 - i : i;
        const float z = depth_m.at<float>(v, u);
        if (z <= 0.0f) continue;
        const double ue = u - shift / z;
        if (emitter_right ? ue >= extreme : ue <= extreme) {
          keep.at<uint8_t>(v, u) = 0;
        } else {
          extreme = ue;
        }
      }
    }
  }
  const double cos_start = std::cos(DegToRad(options.grazing_start_deg));
  const double cos_max = std::cos(DegToRad(options.grazing_max_deg));
  const double fb = options.focal_baseline_px_m;
  const double step = options.disparity_step_px;
  cv::Mat out(h, w, CV_16U, cv::Scalar(0));
  for (int v = 0; v < h; ++v) {
    cv::RNG rng(MixSeed(seed, static_cast<uint64_t>(v)));
    const double y = (v - k.cy) / k.fy;
    for (int u = 0; u < w; ++u) {
      const float z = depth_m.at<float>(v, u);
      if (z <= 0.0f || no_depth_mask.at<uint8_t>(v, u) || !keep.at<uint8_t>(v, u)) continue;
      if (v < options.border_top_px || v >= h - options.border_bottom_px ||
          u < options.border_left_px || u >= w - options.border_right_px) {
        continue;
      }
      if (u > 0 && v > 0 && u < w - 1 && v < h - 1) {
        const float zl = depth_m.at<float>(v, u - 1), zr = depth_m.at<float>(v, u + 1);
        const float zu = depth_m.at<float>(v - 1, u), zd = depth_m.at<float>(v + 1, u);
        const float jump = static_cast<float>(options.discontinuity_relative) * z;
        if (std::abs(zl - z) > jump || std::abs(zr - z) > jump || std::abs(zu - z) > jump ||
            std::abs(zd - z) > jump) {
          if (rng.uniform(0.0, 1.0) < options.discontinuity_dropout) continue;
        } else {
          const double x = (u - k.cx) / k.fx;
          const double dx = 1.0 / k.fx, dy = 1.0 / k.fy;
          const Eigen::Vector3d horizontal((x + dx) * zr - (x - dx) * zl, y * (zr - zl), zr - zl);
          const Eigen::Vector3d vertical(x * (zd - zu), (y + dy) * zd - (y - dy) * zu, zd - zu);
          const Eigen::Vector3d normal = horizontal.cross(vertical);
          const Eigen::Vector3d ray(x, y, 1.0);
          const double norm = normal.norm() * ray.norm();
          if (norm > 0.0) {
            const double cos_incidence = std::abs(normal.dot(ray)) / norm;
            if (cos_incidence < cos_max) continue;
            if (cos_incidence < cos_start &&
                rng.uniform(0.0, 1.0) < (cos_start - cos_incidence) / (cos_start - cos_max)) {
              continue;
            }
          }
        }
      }
      const double z0 = z;
      const double sigma = options.DepthStdDev(z0);
      const double delta = options.DepthStep(z0);
      const double gauss_sigma = std::sqrt(std::max(sigma * sigma - delta * delta / 12.0, 0.0));
      double disparity = fb / z0 + rng.gaussian(gauss_sigma * fb / (z0 * z0));
      if (step > 0.0) disparity = std::round(disparity / step) * step;
      if (disparity <= 0.0) continue;
      const double zm = fb / disparity;
      if (zm < options.min_depth_m || zm > options.max_depth_m) continue;
      out.at<uint16_t>(v, u) = static_cast<uint16_t>(std::lround(zm * 1000.0));
    }
  }
  return out;
}

int CountDifferent(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat differ;
  cv::compare(a, b, differ, cv::CMP_NE);
  return cv::countNonZero(differ.reshape(1));
}

// Simulated frames of the office (hand-held and robot, several sensor variants) give the depth of
// the per-pixel definition to the bit.
TEST(SensorModel, DepthIsThePerPixelDefinitionBitForBit) {
  DepthSensorOptions mirrored;
  mirrored.projector_offset_m = -0.075;
  DepthSensorOptions plain;  // no quantisation, shadow or border; more dropout
  plain.disparity_step_px = 0.0;
  plain.projector_offset_m = 0.0;
  plain.border_left_px = plain.border_right_px = plain.border_top_px = plain.border_bottom_px = 0;
  plain.discontinuity_relative = 0.01;
  plain.grazing_start_deg = 40.0;
  for (const TrajectoryKind kind : {TrajectoryKind::kHandheld, TrajectoryKind::kRobot}) {
    SimulatorOptions sim_options;
    sim_options.trajectory = kind;
    Simulator simulator(sim_options);
    for (const int64_t index : {0, 137, 1450}) {
      const render::RenderedView view =
          simulator.renderer().Render(sim_options.camera, simulator.WorldFromCam(index));
      for (const DepthSensorOptions& options : {DepthSensorOptions(), mirrored, plain}) {
        const uint64_t seed = static_cast<uint64_t>(index) + 7;
        const cv::Mat fast =
            SimulateDepth(view.depth, view.no_depth, sim_options.camera, options, seed);
        const cv::Mat reference =
            ReferenceDepth(view.depth, view.no_depth, sim_options.camera, options, seed);
        ASSERT_GT(cv::countNonZero(reference), 50000) << "frame " << index;
        EXPECT_EQ(CountDifferent(fast, reference), 0) << "frame " << index;
      }
    }
  }
}

// Quantisation rounds half a step away from zero, as std::round does: 5 / 2 m = 2.5 px is 3 px
// (1.667 m), not the 2 px (2.5 m) of rounding to even.
TEST(SensorModel, QuantisationRoundsHalfAStepUp) {
  DepthSensorOptions options;
  options.axial_noise_coeff = 0.0;
  options.focal_baseline_px_m = 5.0;
  options.disparity_step_px = 1.0;
  options.projector_offset_m = 0.0;
  const cv::Mat ideal(48, 64, CV_32F, cv::Scalar(2.0));
  const cv::Mat mask(48, 64, CV_8U, cv::Scalar(0));
  const cv::Mat depth = SimulateDepth(ideal, mask, KinectIntrinsics().Scaled(64, 48), options, 1);
  EXPECT_EQ(depth.at<uint16_t>(24, 20), 1667);
  EXPECT_EQ(CountDifferent(
                depth, ReferenceDepth(ideal, mask, KinectIntrinsics().Scaled(64, 48), options, 1)),
            0);
}

// The colour model as its header defines it, a pixel at a time with cv::saturate_cast.
cv::Mat ReferenceNoise(const cv::Mat& bgr, double gain, const ColorSensorOptions& options,
                       uint64_t seed) {
  cv::Mat out(bgr.size(), CV_8UC3);
  std::vector<float> noise(static_cast<size_t>(bgr.cols) * 3);
  for (int v = 0; v < bgr.rows; ++v) {
    cv::RNG rng(MixSeed(seed, static_cast<uint64_t>(v)));
    cv::Mat noise_row(1, bgr.cols * 3, CV_32F, noise.data());
    rng.fill(noise_row, cv::RNG::NORMAL, 0.0, 1.0);
    for (int i = 0; i < bgr.cols * 3; ++i) {
      const float level = static_cast<float>(gain) * bgr.ptr<uint8_t>(v)[i];
      const float value = level + noise[static_cast<size_t>(i)] *
                                      (static_cast<float>(options.read_noise) +
                                       static_cast<float>(options.shot_noise) * std::sqrt(level));
      out.ptr<uint8_t>(v)[i] = cv::saturate_cast<uint8_t>(value);
    }
  }
  return out;
}

// Gain and noise give the bytes of the per-pixel definition, clipped at both ends included.
TEST(SensorModel, ColourNoiseIsThePerPixelDefinitionBitForBit) {
  cv::Mat bgr(97, 131, CV_8UC3);
  cv::RNG(5).fill(bgr, cv::RNG::UNIFORM, 0, 256);
  ColorSensorOptions options;
  options.read_noise = 9.0;  // enough to push dark pixels below 0 and bright ones above 255
  int clipped_white = 0, clipped_black = 0;
  for (const double gain : {0.5, 1.0, 1.7}) {
    const cv::Mat fast = SimulateColor(bgr, gain, Eigen::Vector2d::Zero(), options, 11);
    const cv::Mat reference = ReferenceNoise(bgr, gain, options, 11);
    EXPECT_EQ(CountDifferent(fast, reference), 0) << "gain " << gain;
    clipped_white += cv::countNonZero(fast.reshape(1) == 255);
    clipped_black += cv::countNonZero(fast.reshape(1) == 0);
  }
  EXPECT_GT(clipped_white, 1000);
  EXPECT_GT(clipped_black, 100);
}

TEST(SensorModel, OptionsAreChecked) {
  DepthSensorOptions depth;
  std::string error;
  EXPECT_TRUE(depth.Check(&error));
  depth.max_depth_m = 66.0;  // beyond 16-bit millimetres
  EXPECT_FALSE(depth.Check(&error));
  depth.max_depth_m = 0.2;
  EXPECT_FALSE(depth.Check(&error));
  EXPECT_THROW(SimulateDepth(cv::Mat(4, 4, CV_32F, cv::Scalar(1)),
                             cv::Mat(4, 4, CV_8U, cv::Scalar(0)), KinectIntrinsics(), depth, 1),
               InvalidArgument);
}

}  // namespace
}  // namespace sightmap::sim
