// One registered RGB-D frame, the unit every source produces and every later stage consumes.
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace sightmap {

// Nanoseconds since the start of the stream (recordings) or the epoch (live devices).
using TimestampNs = int64_t;
inline constexpr TimestampNs kNsPerMs = 1'000'000;

// A camera pose at a time: one line of a TUM trajectory, one pose of an estimate.
struct StampedPose {
  TimestampNs timestamp_ns = 0;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
};

struct RgbdFrame {
  // Position in the source's stream of paired frames, 0-based.
  int64_t index = 0;
  // The depth frame's timestamp; the colour frame was taken within the source's sync tolerance.
  TimestampNs timestamp_ns = 0;
  // 8-bit colour, 3 channels in OpenCV's BGR order (so cv::imwrite and cv::imshow take it as is).
  cv::Mat color;
  // 16-bit depth [mm], 0 = no measurement, registered to `color`: same size, same camera.
  cv::Mat depth;
  // Ground truth world_from_cam where the source has it (image folders), for evaluation only.
  std::optional<Eigen::Isometry3d> world_from_cam_gt;

  // Depth [m] at a pixel, or 0 where there is no measurement.
  double DepthMeters(int u, int v) const { return depth.at<uint16_t>(v, u) * 1e-3; }
};

// Fraction of depth pixels with a measurement, in [0, 1].
double ValidDepthFraction(const cv::Mat& depth_mm);

}  // namespace sightmap
