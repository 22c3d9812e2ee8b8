#include "capture/keyframe_sampler.h"

#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::capture {
namespace {

std::vector<int64_t> SampleMs(KeyframeSampler& sampler, const std::vector<int64_t>& times_ms) {
  std::vector<int64_t> kept;
  for (int64_t t : times_ms) {
    if (sampler.Accept(t * kNsPerMs)) kept.push_back(t);
  }
  return kept;
}

TEST(KeyframeSampler, OneHertzFromThirtyHertzKeepsOnePerSecond) {
  KeyframeSampler sampler;
  std::vector<int64_t> times;
  for (int i = 0; i < 30 * 60; ++i) times.push_back(i * 1000 / 30);  // one minute at 30 Hz
  const std::vector<int64_t> kept = SampleMs(sampler, times);
  ASSERT_EQ(kept.size(), 60u);
  for (size_t i = 0; i < kept.size(); ++i) {
    EXPECT_GE(kept[i], static_cast<int64_t>(i) * 1000);
    EXPECT_LT(kept[i], static_cast<int64_t>(i) * 1000 + 34);  // the first frame at or after i s
  }
}

TEST(KeyframeSampler, JitterDoesNotDrift) {
  KeyframeSampler sampler;
  std::vector<int64_t> times;
  // Frames at 30 Hz with +-5 ms jitter, ten minutes long.
  for (int i = 0; i < 30 * 600; ++i) times.push_back(i * 1000 / 30 + ((i * 7919) % 11) - 5 + 10);
  EXPECT_EQ(SampleMs(sampler, times).size(), 600u);
}

TEST(KeyframeSampler, GapSkipsMissedSlotsAndBackwardsTimeReanchors) {
  KeyframeSampler sampler;
  EXPECT_EQ(SampleMs(sampler, {0, 500, 1000, 4200, 4500, 5000, 5300, 100, 600, 1100}),
            (std::vector<int64_t>{0, 1000, 4200, 5000, 100, 1100}));
}

// A replay resumed after a stored keyframe taken off the grid (early, where tracking was about to
// lose its overlap) accepts that keyframe first: it must keep the whole replay's grid after it,
// not start one of its own half a second off.
TEST(KeyframeSampler, AStreamResumedOffTheGridKeepsTheWholeStreamsGrid) {
  std::vector<int64_t> times;
  for (int i = 0; i < 100; ++i) times.push_back(i * 100);  // ten seconds at 10 Hz
  KeyframeSampler whole;
  std::vector<int64_t> whole_kept;
  for (int64_t t : SampleMs(whole, times)) {
    if (t > 4500) whole_kept.push_back(t);
  }
  KeyframeSampler resumed;
  std::vector<int64_t> resumed_times;
  for (int64_t t : times) {
    if (t >= 4500) resumed_times.push_back(t);
  }
  std::vector<int64_t> resumed_kept = SampleMs(resumed, resumed_times);
  ASSERT_EQ(resumed_kept.front(), 4500);  // the stored keyframe
  resumed_kept.erase(resumed_kept.begin());
  EXPECT_EQ(resumed_kept, whole_kept);
  EXPECT_EQ(resumed_kept.front(), 5000);
  // Clocks that start below zero keep whole periods too.
  KeyframeSampler negative;
  EXPECT_EQ(SampleMs(negative, {-1500, -1200, -1000, -100, 0, 700, 1000}),
            (std::vector<int64_t>{-1500, -1000, 0, 1000}));
}

TEST(KeyframeSampler, ZeroRateKeepsEverythingAndOptionsAreChecked) {
  KeyframeSamplerOptions options;
  options.rate_hz = 0.0;
  KeyframeSampler sampler(options);
  EXPECT_EQ(SampleMs(sampler, {0, 1, 2, 3}).size(), 4u);
  options.rate_hz = -1.0;
  EXPECT_THROW(KeyframeSampler{options}, InvalidArgument);
}

TEST(KeyframeSampler, TwoHertz) {
  KeyframeSamplerOptions options;
  options.rate_hz = 2.0;
  KeyframeSampler sampler(options);
  std::vector<int64_t> times;
  for (int i = 0; i < 300; ++i) times.push_back(i * 1000 / 30);  // ten seconds
  EXPECT_EQ(SampleMs(sampler, times).size(), 20u);
}

}  // namespace
}  // namespace sightmap::capture
