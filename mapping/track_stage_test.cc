// The tracking stage on the simulator's frames: every frame tracked and keyframes at the rate asked
// for, frames handed on as keyframes when tracking is off, and how the stage ends.
#include "mapping/track_stage.h"

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "sim/simulator.h"

namespace sightmap::mapping {
namespace {

sim::Simulator TenHzWalk(int frames) {
  sim::SimulatorOptions options;
  options.fps = 10.0;
  options.frames = frames;
  options.seed = 11;
  return sim::Simulator(options);
}

void Feed(sim::Simulator& simulator, BoundedQueue<RgbdFrame>* frames) {
  for (int64_t i = 0; i < simulator.num_frames(); ++i) {
    if (!frames->Push(simulator.RenderFrame(i))) break;
  }
  frames->Close();
}

std::vector<KeyframeItem> Drain(BoundedQueue<KeyframeItem>* keyframes) {
  std::vector<KeyframeItem> items;
  while (std::optional<KeyframeItem> item = keyframes->Pop()) items.push_back(std::move(*item));
  return items;
}

TEST(TrackStage, TracksEveryFrameAndEmitsKeyframesAtTheRate) {
  sim::Simulator simulator = TenHzWalk(31);  // 3 s at 10 Hz
  BoundedQueue<RgbdFrame> frames(2);
  BoundedQueue<KeyframeItem> keyframes(64);
  TrackStageOptions options;
  options.tracker.keyframe_rate_hz = 1.0;
  TrackStage stage(simulator.options().camera, options, &frames, &keyframes);
  Feed(simulator, &frames);
  const std::vector<KeyframeItem> items = Drain(&keyframes);
  stage.Join();
  EXPECT_EQ(stage.error(), nullptr);
  EXPECT_EQ(stage.tracked_frames(), 31);
  EXPECT_EQ(stage.report().frame_s.size(), 31u);
  EXPECT_EQ(stage.report().counters.frames, 31);
  // At least one a second (frames 0, 10, 20, 30), more where the overlap ran out early.
  ASSERT_GE(items.size(), 4u);
  EXPECT_EQ(items.front().keyframe.frame.index, 0);
  EXPECT_FALSE(items.front().keyframe.motion.has_value()) << "the first keyframe has no motion";
  for (size_t i = 0; i < items.size(); ++i) {
    EXPECT_TRUE(items[i].tracked);
    EXPECT_GT(items[i].keyframe.features.size(), 0u);
    EXPECT_FALSE(items[i].keyframe.depth_small.empty());
    if (i > 0) {
      EXPECT_GT(items[i].keyframe.frame.index, items[i - 1].keyframe.frame.index);
      EXPECT_TRUE(items[i].keyframe.motion.has_value());
    }
  }
}

TEST(TrackStage, WithoutTrackingEveryFrameGoesOnAsAKeyframe) {
  sim::Simulator simulator = TenHzWalk(5);
  BoundedQueue<RgbdFrame> frames(2);
  BoundedQueue<KeyframeItem> keyframes(8);
  TrackStageOptions options;
  options.track = false;
  TrackStage stage(simulator.options().camera, options, &frames, &keyframes);
  Feed(simulator, &frames);
  const std::vector<KeyframeItem> items = Drain(&keyframes);
  stage.Join();
  ASSERT_EQ(items.size(), 5u);
  for (size_t i = 0; i < items.size(); ++i) {
    EXPECT_FALSE(items[i].tracked);
    EXPECT_EQ(items[i].keyframe.frame.index, static_cast<int64_t>(i));
    EXPECT_EQ(items[i].keyframe.features.size(), 0u) << "the mapper computes them";
  }
  EXPECT_EQ(stage.tracked_frames(), 0);
}

TEST(TrackStage, AFrameTheTrackerRefusesEndsTheStageWithTheError) {
  sim::Simulator simulator = TenHzWalk(2);
  BoundedQueue<RgbdFrame> frames(4);
  BoundedQueue<KeyframeItem> keyframes(4);
  TrackStage stage(simulator.options().camera, TrackStageOptions(), &frames, &keyframes);
  RgbdFrame frame = simulator.RenderFrame(0);
  cv::resize(frame.color, frame.color, cv::Size(320, 240));  // not the camera's size
  frames.Push(std::move(frame));
  EXPECT_TRUE(Drain(&keyframes).empty());
  stage.Join();
  EXPECT_NE(stage.error(), nullptr);
  EXPECT_FALSE(frames.Push(simulator.RenderFrame(1))) << "the input is closed: capture stops";
}

TEST(TrackStage, StopsWhenTheMappingStageTakesNoMoreKeyframes) {
  sim::Simulator simulator = TenHzWalk(3);
  BoundedQueue<RgbdFrame> frames(4);
  BoundedQueue<KeyframeItem> keyframes(1);
  keyframes.Close();  // mapping stopped
  TrackStage stage(simulator.options().camera, TrackStageOptions(), &frames, &keyframes);
  frames.Push(simulator.RenderFrame(0));  // after it the stage finds the queue closed
  stage.Join();                           // returns although the input was never closed
  EXPECT_EQ(stage.tracked_frames(), 1);
  EXPECT_EQ(stage.error(), nullptr);
}

}  // namespace
}  // namespace sightmap::mapping
