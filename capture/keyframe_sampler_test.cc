#include "capture/keyframe_sampler.h"

#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::capture {
namespace {

constexpr int64_t kMs = 1'000'000;

std::vector<int64_t> SampleMs(KeyframeSampler& sampler, const std::vector<int64_t>& times_ms) {
  std::vector<int64_t> kept;
  for (int64_t t : times_ms) {
    if (sampler.Accept(t * kMs)) kept.push_back(t);
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
