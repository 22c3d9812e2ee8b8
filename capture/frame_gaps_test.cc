#include "capture/frame_gaps.h"

#include <gtest/gtest.h>

namespace sightmap::capture {
namespace {

TEST(FrameGaps, ARecordingCountsTheFramesSkippedBeforeAndBetweenReads) {
  FrameGaps gaps(1);
  EXPECT_EQ(gaps.Add(1), 0);
  EXPECT_EQ(gaps.Add(2), 0);
  EXPECT_EQ(gaps.Add(6), 3);  // 3, 4 and 5 were replaced before they were read
  EXPECT_EQ(gaps.Add(7), 0);
  EXPECT_EQ(gaps.missed(), 3);

  FrameGaps late_start(1);
  EXPECT_EQ(late_start.Add(3), 2);
  EXPECT_EQ(late_start.missed(), 2);
}

TEST(FrameGaps, ALiveDeviceCountsFromItsFirstReadFrameAndARestartStartsAgain) {
  FrameGaps gaps(std::nullopt);
  EXPECT_EQ(gaps.Add(5000), 0);
  EXPECT_EQ(gaps.Add(5002), 1);
  EXPECT_EQ(gaps.Add(1), 0);  // the device restarted its count
  EXPECT_EQ(gaps.Add(2), 0);
  EXPECT_EQ(gaps.Add(2), 0);  // a repeated number is not a gap
  EXPECT_EQ(gaps.missed(), 1);
}

}  // namespace
}  // namespace sightmap::capture
