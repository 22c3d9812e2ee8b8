// The simulated frames held against the real recordings in ../shared/data: the share of valid
// depth pixels and the ORB keypoints found (of 1000 asked) per frame, printed side by side. The
// real data measured 68-87% valid depth and 870-1000 keypoints; the simulator must fall in those
// ranges.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/rgbd_source.h"
#include "sim/simulator.h"
#include "tests/test_data.h"

namespace sightmap::sim {
namespace {

struct FrameStatistics {
  std::vector<double> valid_depth;  // share of pixels with depth, per frame
  std::vector<double> keypoints;    // ORB keypoints found of 1000, per frame
  std::vector<double> shadow_px;    // mean width of no-depth runs left of depth edges [px]

  void Add(const RgbdFrame& frame) {
    valid_depth.push_back(ValidDepthFraction(frame.depth));
    cv::Mat gray;
    cv::cvtColor(frame.color, gray, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keys;
    cv::ORB::create(1000)->detect(gray, keys);
    keypoints.push_back(static_cast<double>(keys.size()));
  }
  static double Mean(const std::vector<double>& v) {
    double sum = 0;
    for (double x : v) sum += x;
    return v.empty() ? 0.0 : sum / v.size();
  }
  static double Min(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
  static double Max(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }
};

FrameStatistics FromSource(const std::string& source, int max_frames, int stride) {
  FrameStatistics stats;
  auto reader = capture::OpenSource(source);
  int index = 0;
  while (auto frame = reader->Next()) {
    if (index++ % stride != 0) continue;
    stats.Add(*frame);
    if (static_cast<int>(stats.valid_depth.size()) >= max_frames) break;
  }
  return stats;
}

FrameStatistics FromSimulator(TrajectoryKind kind, int frames) {
  SimulatorOptions options;
  options.trajectory = kind;
  options.fps = 1.0;
  options.seed = 11;
  Simulator simulator(options);
  FrameStatistics stats;
  // Spread over the walk: corridor, rooms, close to walls and across rooms.
  for (int i = 0; i < frames; ++i) stats.Add(simulator.RenderFrame(7 + 23 * i));
  return stats;
}

void Print(const char* name, const FrameStatistics& s) {
  std::printf("%-28s %3zu frames  valid depth %5.1f%% (%5.1f-%5.1f)  ORB %6.1f (%4.0f-%4.0f)\n",
              name, s.valid_depth.size(), 100 * FrameStatistics::Mean(s.valid_depth),
              100 * FrameStatistics::Min(s.valid_depth), 100 * FrameStatistics::Max(s.valid_depth),
              FrameStatistics::Mean(s.keypoints), FrameStatistics::Min(s.keypoints),
              FrameStatistics::Max(s.keypoints));
  std::printf("%-28s per frame: ", "");
  for (size_t i = 0; i < s.keypoints.size(); ++i) {
    std::printf("%.0f%%/%.0f ", 100 * s.valid_depth[i], s.keypoints[i]);
  }
  std::printf("\n");
}

TEST(SimStatistics, SimulatedFramesMatchTheRealRecordings) {
  SIGHTMAP_REQUIRE_SHARED_DATA(oni, "oni/kinect-12f.oni");
  SIGHTMAP_REQUIRE_SHARED_DATA(lounge, "rgbd/3dmatch-lounge/seq-01");
  const FrameStatistics kinect = FromSource(oni, 12, 1);
  const FrameStatistics threedmatch = FromSource("3dmatch:" + lounge, 12, 1);
  const FrameStatistics handheld = FromSimulator(TrajectoryKind::kHandheld, 12);
  const FrameStatistics robot = FromSimulator(TrajectoryKind::kRobot, 12);
  std::printf("\n%-28s %s\n", "source", "per-frame statistics: mean (min-max)");
  Print("real: kinect-12f.oni", kinect);
  Print("real: 3dmatch-lounge seq-01", threedmatch);
  Print("sim: office handheld", handheld);
  Print("sim: office robot", robot);

  // The real recordings' ranges, as measured (and re-measured here).
  for (const FrameStatistics* real : {&kinect, &threedmatch}) {
    EXPECT_GE(FrameStatistics::Mean(real->valid_depth), 0.68);
    EXPECT_LE(FrameStatistics::Mean(real->valid_depth), 0.87);
  }
  for (const FrameStatistics* sim : {&handheld, &robot}) {
    EXPECT_GE(FrameStatistics::Mean(sim->valid_depth), 0.68);
    EXPECT_LE(FrameStatistics::Mean(sim->valid_depth), 0.87);
    EXPECT_GE(FrameStatistics::Mean(sim->keypoints), 870.0);
    EXPECT_LE(FrameStatistics::Mean(sim->keypoints), 1000.0);
  }
}

}  // namespace
}  // namespace sightmap::sim
