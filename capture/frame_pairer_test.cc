#include "capture/frame_pairer.h"

#include <vector>

#include <gtest/gtest.h>

namespace sightmap::capture {
namespace {

// Images carry their own timestamp as a pixel so a test can tell which frame was paired.
TimedImage Stamp(int64_t t_ms) {
  return {t_ms * kNsPerMs, cv::Mat(1, 1, CV_32SC1, cv::Scalar(static_cast<int>(t_ms)))};
}

std::vector<std::pair<int, int>> Drain(FramePairer& pairer) {
  std::vector<std::pair<int, int>> pairs;
  while (auto pair = pairer.PopPair()) {
    pairs.emplace_back(pair->first.image.at<int>(0), pair->second.image.at<int>(0));
  }
  return pairs;
}

TEST(FramePairer, ColourBeforeDepthPairsWithTheNearer) {
  // kinect-12f.oni order: colour at 0, depth at 11.7 ms, colour at 33.3 ms, ...
  FramePairer pairer(20 * kNsPerMs);
  pairer.AddColor(Stamp(0));
  pairer.AddDepth(Stamp(12));
  pairer.AddColor(Stamp(33));
  pairer.AddDepth(Stamp(45));
  pairer.Finish();
  EXPECT_EQ(Drain(pairer), (std::vector<std::pair<int, int>>{{12, 0}, {45, 33}}));
  EXPECT_EQ(pairer.unpaired_depth_frames(), 0);
}

TEST(FramePairer, DepthWaitsForALaterCloserColourFrame) {
  FramePairer pairer(20 * kNsPerMs);
  pairer.AddColor(Stamp(0));
  pairer.AddDepth(Stamp(30));
  EXPECT_TRUE(Drain(pairer).empty());  // colour at 33 may still come
  pairer.AddColor(Stamp(33));
  EXPECT_EQ(Drain(pairer), (std::vector<std::pair<int, int>>{{30, 33}}));
}

TEST(FramePairer, DepthRunningAFrameAheadOfColourStillPairsFrameForFrame) {
  // OpenNI2's dummy device, now and then: depth k+1 arrives before colour k, every frame.
  FramePairer pairer(20 * kNsPerMs);
  pairer.AddDepth(Stamp(0));
  for (int k = 0; k < 10; ++k) {
    pairer.AddDepth(Stamp((k + 1) * 33));
    pairer.AddColor(Stamp(k * 33));
  }
  std::vector<std::pair<int, int>> expected;
  for (int k = 0; k < 10; ++k) expected.emplace_back(k * 33, k * 33);
  EXPECT_EQ(Drain(pairer), expected);
  EXPECT_EQ(pairer.unpaired_depth_frames(), 0);
}

TEST(FramePairer, LastDepthWithoutPartnerIsCountedUnpaired) {
  // openni2-24f.oni ends with a depth frame 30 ms after the last colour frame.
  FramePairer pairer(20 * kNsPerMs);
  pairer.AddDepth(Stamp(734));
  pairer.AddColor(Stamp(737));
  pairer.AddDepth(Stamp(767));
  pairer.Finish();
  EXPECT_EQ(Drain(pairer), (std::vector<std::pair<int, int>>{{734, 737}}));
  EXPECT_EQ(pairer.unpaired_depth_frames(), 1);
}

TEST(FramePairer, DeadColourStreamDoesNotGrowWithoutBound) {
  FramePairer pairer(20 * kNsPerMs);
  for (int i = 0; i < 100; ++i) pairer.AddDepth(Stamp(i * 33));
  EXPECT_TRUE(Drain(pairer).empty());
  EXPECT_GE(pairer.unpaired_depth_frames(), 90);
  pairer.Finish();
  EXPECT_EQ(pairer.unpaired_depth_frames(), 100);
}

TEST(FramePairer, SlowColourStreamServesSeveralDepthFrames) {
  FramePairer pairer(20 * kNsPerMs);
  pairer.AddColor(Stamp(0));
  pairer.AddDepth(Stamp(1));
  pairer.AddDepth(Stamp(15));
  pairer.AddColor(Stamp(66));
  pairer.Finish();
  EXPECT_EQ(Drain(pairer), (std::vector<std::pair<int, int>>{{1, 0}, {15, 0}}));
  EXPECT_EQ(pairer.unpaired_depth_frames(), 0);
}

}  // namespace
}  // namespace sightmap::capture
