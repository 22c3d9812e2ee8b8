// The capture stage on the simulator: which frames go on, a replay that waits, a live sensor that
// drops and counts, a failing source, and stopping while the stage waits for room.
#include "mapping/capture_stage.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/thread_priority.h"
#include "mapping/source_testing.h"
#include "sim/sim_source.h"

namespace sightmap::mapping {
namespace {

std::unique_ptr<capture::RgbdSource> Walk(int frames, double fps = 10.0) {
  sim::SimulatorOptions options;
  options.fps = fps;
  options.frames = frames;
  return sim::OpenSimSource(options);
}

std::vector<int64_t> DrainIndices(BoundedQueue<RgbdFrame>* frames) {
  std::vector<int64_t> indices;
  while (std::optional<RgbdFrame> frame = frames->Pop()) indices.push_back(frame->index);
  return indices;
}

TEST(CaptureStage, AReplayPassesEveryNthFrameFromTheStartFrameAndDropsNone) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(20);
  BoundedQueue<RgbdFrame> frames(1);  // the stage must wait for the slow reader below
  CaptureStageOptions options;
  options.start_frame = 3;
  options.take_every = 2;
  CaptureStage stage(source.get(), options, &frames);
  std::vector<int64_t> indices;
  while (std::optional<RgbdFrame> frame = frames.Pop()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    indices.push_back(frame->index);
  }
  stage.Join();
  EXPECT_EQ(indices, (std::vector<int64_t>{3, 5, 7, 9, 11, 13, 15, 17, 19}));
  EXPECT_EQ(stage.frames_read(), 20);
  EXPECT_EQ(stage.dropped_frames(), 0);
  EXPECT_FALSE(stage.error().has_value());
}

// A real source behind a counter of the frames it produced; `can_peek` false hides PeekStamp, as
// a source that cannot tell a frame's stamp without decoding it.
class CountingSource : public testing::ForwardingSource {
 public:
  CountingSource(std::unique_ptr<capture::RgbdSource> source, bool can_peek)
      : ForwardingSource(std::move(source)), can_peek_(can_peek) {}
  std::optional<RgbdFrame> Next() override {
    std::optional<RgbdFrame> frame = ForwardingSource::Next();
    produced += frame ? 1 : 0;
    return frame;
  }
  std::optional<FrameStamp> PeekStamp() const override {
    return can_peek_ ? ForwardingSource::PeekStamp() : std::nullopt;
  }
  int produced = 0;

 private:
  bool can_peek_;
};

// A resumed replay starts after the last stored frame's time: the simulator passes over the
// mapped frames without rendering them; a source that cannot peek reads and drops them.
TEST(CaptureStage, AResumedReplayPassesOverMappedFramesWithoutProducingThem) {
  std::unique_ptr<capture::RgbdSource> probe = Walk(40);
  for (int i = 0; i < 24; ++i) probe->SkipNext();
  const TimestampNs last_stored = probe->PeekStamp()->timestamp_ns;  // frame 24's
  for (const bool can_peek : {true, false}) {
    CountingSource source(Walk(40), can_peek);
    BoundedQueue<RgbdFrame> frames(4);
    CaptureStageOptions options;
    options.after_timestamp_ns = last_stored;
    CaptureStage stage(&source, options, &frames);
    const std::vector<int64_t> indices = DrainIndices(&frames);
    stage.Join();
    ASSERT_EQ(indices.size(), 15u) << can_peek;
    EXPECT_EQ(indices.front(), 25) << can_peek;
    EXPECT_EQ(stage.frames_skipped(), 25) << can_peek;
    EXPECT_EQ(stage.frames_read(), 40) << can_peek;
    EXPECT_EQ(source.produced, can_peek ? 15 : 40) << can_peek;
  }
}

TEST(CaptureStage, WithoutTrackingOneFramePerKeyframePeriodGoesOn) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(30);  // 3 s at 10 Hz
  BoundedQueue<RgbdFrame> frames(4);
  CaptureStageOptions options;
  options.sample_keyframes = true;
  options.sampler.rate_hz = 1.0;
  CaptureStage stage(source.get(), options, &frames);
  EXPECT_EQ(DrainIndices(&frames), (std::vector<int64_t>{0, 10, 20}));
  stage.Join();
  EXPECT_EQ(stage.frames_read(), 30);
}

TEST(CaptureStage, ALiveSensorNeverWaitsAndTheTrackerGetsTheNewestFrames) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(12);
  BoundedQueue<RgbdFrame> frames(2);
  CaptureStageOptions options;
  options.live = true;
  CaptureStage stage(source.get(), options, &frames);
  stage.Join();  // nobody reads until the sensor's stream ended: it did not wait
  EXPECT_EQ(stage.frames_read(), 12);
  EXPECT_EQ(stage.dropped_frames(), 10);
  EXPECT_EQ(DrainIndices(&frames), (std::vector<int64_t>{10, 11})) << "the oldest were dropped";
}

// A source that loses every third frame before it is read, as OpenNI2 does behind a live pace.
class MissingSource : public testing::ForwardingSource {
 public:
  using ForwardingSource::ForwardingSource;
  std::optional<RgbdFrame> Next() override {
    std::optional<RgbdFrame> frame = ForwardingSource::Next();
    if (frame && frame->index % 3 == 2) {
      ++missed_;
      frame = ForwardingSource::Next();
    }
    return frame;
  }
  // Which frame comes next is not known until it arrives.
  std::optional<FrameStamp> PeekStamp() const override { return std::nullopt; }
  capture::SourceStats stats() const override {
    capture::SourceStats stats = ForwardingSource::stats();
    stats.missed_depth_frames = missed_;
    return stats;
  }

 private:
  int64_t missed_ = 0;
};

TEST(CaptureStage, FramesTheSourceMissedCountAsDroppedAndAsPassed) {
  MissingSource source(Walk(12));
  BoundedQueue<RgbdFrame> frames(16);
  CaptureStageOptions options;
  options.live = true;
  CaptureStage stage(&source, options, &frames);
  stage.Join();
  EXPECT_EQ(DrainIndices(&frames), (std::vector<int64_t>{0, 1, 3, 4, 6, 7, 9, 10}));
  EXPECT_EQ(stage.frames_read(), 8);
  EXPECT_EQ(stage.dropped_frames(), 4) << "none from the queue, four in the source";
  EXPECT_EQ(stage.frames_passed(), 12);
}

TEST(CaptureStage, AFailingSourceEndsTheStreamWithItsReason) {
  testing::FailingSource source(Walk(20), 4);
  BoundedQueue<RgbdFrame> frames(8);
  CaptureStage stage(&source, CaptureStageOptions(), &frames);
  EXPECT_EQ(DrainIndices(&frames), (std::vector<int64_t>{0, 1, 2, 3}));
  stage.Join();
  ASSERT_TRUE(stage.error().has_value());
  EXPECT_NE(stage.error()->find("unplugged"), std::string::npos) << *stage.error();
}

TEST(CaptureStage, StopEndsAReplayWaitingForRoomAndDiscardsWhatIsQueued) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(50);
  BoundedQueue<RgbdFrame> frames(1);
  CaptureStage stage(source.get(), CaptureStageOptions(), &frames);
  while (frames.size() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  stage.Stop();
  stage.Join();
  EXPECT_LT(stage.frames_read(), 5);  // it was waiting for room, not reading on
  EXPECT_EQ(frames.size(), 0u);
  EXPECT_FALSE(frames.Pop().has_value());
}

TEST(CaptureStage, ALiveSensorStopsReadingOnceNobodyTakesFrames) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(50);
  BoundedQueue<RgbdFrame> frames(1);
  frames.Close();  // the tracking stage ended
  CaptureStageOptions options;
  options.live = true;
  CaptureStage stage(source.get(), options, &frames);
  stage.Join();
  EXPECT_EQ(stage.frames_read(), 1);
  EXPECT_EQ(stage.dropped_frames(), 0);
}

// The simulator's frames, noting the nice value of the thread that reads them.
class PrioritySource : public testing::ForwardingSource {
 public:
  using ForwardingSource::ForwardingSource;
  std::optional<RgbdFrame> Next() override {
    nice = ThisThreadsNice();
    return ForwardingSource::Next();
  }
  std::atomic<int> nice{-100};
};

TEST(CaptureStage, AReplayReadsAtALowerPriorityThanTheStagesItFeedsALiveSensorDoesNot) {
  const int base = ThisThreadsNice();
  for (const bool live : {false, true}) {
    PrioritySource source(Walk(2));
    BoundedQueue<RgbdFrame> frames(4);
    CaptureStageOptions options;
    options.live = live;
    options.replay_nice_increment = 4;
    CaptureStage stage(&source, options, &frames);
    stage.Join();
    EXPECT_EQ(source.nice.load(), live ? base : std::min(19, base + 4)) << "live " << live;
  }
  EXPECT_EQ(ThisThreadsNice(), base);  // the stages' own threads keep theirs
}

TEST(CaptureStage, BadOptionsAreRefused) {
  const std::unique_ptr<capture::RgbdSource> source = Walk(1);
  BoundedQueue<RgbdFrame> frames(1);
  CaptureStageOptions options;
  options.take_every = 0;
  EXPECT_THROW(CaptureStage(source.get(), options, &frames), InvalidArgument);
  options = CaptureStageOptions();
  options.start_frame = -1;
  EXPECT_THROW(CaptureStage(source.get(), options, &frames), InvalidArgument);
  options = CaptureStageOptions();
  options.replay_nice_increment = 20;
  EXPECT_THROW(CaptureStage(source.get(), options, &frames), InvalidArgument);
  options.replay_nice_increment = -1;
  EXPECT_THROW(CaptureStage(source.get(), options, &frames), InvalidArgument);
  EXPECT_THROW(CaptureStage(nullptr, CaptureStageOptions(), &frames), Error);
}

}  // namespace
}  // namespace sightmap::mapping
