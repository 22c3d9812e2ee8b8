#include "store/synthetic_model.h"

#include <cmath>
#include <random>

#include "core/check.h"

namespace sightmap::store {

bool SyntheticKeyframeOptions::Check(std::string* error) const {
  auto fail = [error](const char* message) {
    if (error) *error = message;
    return false;
  };
  if (width < 8 || height < 8) return fail("width and height must be >= 8 px");
  if (num_features < 0) return fail("num_features must be >= 0");
  if (!(wall_distance_m > 0.1 && wall_distance_m < 60.0)) {
    return fail("wall_distance_m must be in (0.1, 60) m (16-bit millimetre depth)");
  }
  return true;
}

Intrinsics SyntheticIntrinsics(int width, int height) {
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = 570.3 * width / 640.0;
  k.fy = 570.3 * height / 480.0;
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  return k;
}

KeyframeRecord MakeSyntheticKeyframe(SessionId session, int index,
                                     const SyntheticKeyframeOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  KeyframeRecord keyframe;
  keyframe.session = session;
  keyframe.timestamp_ns = static_cast<int64_t>(index) * 1000000000;  // 1 Hz keyframes
  keyframe.intrinsics = SyntheticIntrinsics(options.width, options.height);
  keyframe.world_from_cam = Eigen::Isometry3d::Identity();
  keyframe.world_from_cam.translation() = Eigen::Vector3d(index * options.step_m, 0.0, 0.0);
  keyframe.odom_world_from_cam = keyframe.world_from_cam;

  const Intrinsics& k = keyframe.intrinsics;
  const double shift_m = index * options.step_m;
  keyframe.color.create(options.height, options.width, CV_8UC3);
  keyframe.depth.create(options.height, options.width, CV_16UC1);
  const uint16_t depth_mm = static_cast<uint16_t>(std::lround(options.wall_distance_m * 1000.0));
  for (int v = 0; v < options.height; ++v) {
    auto* bgr = keyframe.color.ptr<cv::Vec3b>(v);
    auto* depth = keyframe.depth.ptr<uint16_t>(v);
    for (int u = 0; u < options.width; ++u) {
      // Texture fixed to the wall (world x, y), so consecutive keyframes see the same pattern.
      const double x = (u - k.cx) / k.fx * options.wall_distance_m + shift_m;
      const double y = (v - k.cy) / k.fy * options.wall_distance_m;
      const double a = std::sin(x * 9.0) * std::cos(y * 7.0);
      const double b = std::sin((x + y) * 23.0);
      bgr[u] = cv::Vec3b(static_cast<uint8_t>(128 + 100 * a), static_cast<uint8_t>(128 + 90 * b),
                         static_cast<uint8_t>(128 + 60 * a * b));
      depth[u] = depth_mm;
    }
  }

  std::mt19937 random(static_cast<uint32_t>(index) * 7919u + 17u);
  std::uniform_real_distribution<float> along_u(0.0f, static_cast<float>(options.width - 1));
  std::uniform_real_distribution<float> along_v(0.0f, static_cast<float>(options.height - 1));
  std::uniform_int_distribution<int> byte(0, 255);
  Features& features = keyframe.features;
  features.descriptors.create(options.num_features, 32, CV_8U);
  for (int i = 0; i < options.num_features; ++i) {
    const float u = along_u(random);
    const float v = along_v(random);
    features.keypoints.emplace_back(u, v, 31.0f, static_cast<float>(i % 360), 0.001f * (i % 97),
                                    i % 8, -1);
    for (int j = 0; j < 32; ++j)
      features.descriptors.at<uint8_t>(i, j) = static_cast<uint8_t>(byte(random));
    features.points_cam.push_back(k.Unproject(u, v, options.wall_distance_m));
    features.has_point.push_back(true);
  }
  return keyframe;
}

}  // namespace sightmap::store
