// The map stage on the simulator's 1 Hz walk: what each keyframe hands the writer, in order, the
// anchor to ground truth, the accuracy figure, and a keyframe without the ground truth it needs.
#include "mapping/map_stage.h"

#include <algorithm>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include "core/link_type.h"
#include "sim/simulator.h"
#include "slam/tracker.h"

namespace sightmap::mapping {
namespace {

sim::Simulator OneHzWalk(int frames) {
  sim::SimulatorOptions options;
  options.fps = 1.0;
  options.frames = frames;
  options.seed = 11;
  return sim::Simulator(options);
}

KeyframeItem Untracked(RgbdFrame frame) {
  KeyframeItem item;
  item.keyframe.frame = std::move(frame);
  return item;
}

TEST(MapStage, EachKeyframeBecomesItsWriteTasksInOrder) {
  sim::Simulator simulator = OneHzWalk(34);
  const Intrinsics camera = simulator.options().camera;
  slam::Mapper mapper(camera);
  MapStage stage(&mapper, SessionId(1), camera, MapStageOptions(), RestoredModel());
  int vocabularies = 0;
  int pose_updates = 0;
  std::vector<StampedPose> truths;
  for (int64_t i = 0; i < simulator.num_frames(); ++i) {
    RgbdFrame frame = simulator.RenderFrame(i);
    truths.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
    const std::vector<WriteTask> tasks = stage.Map(Untracked(std::move(frame)));
    ASSERT_FALSE(tasks.empty());
    const WriteTask& keyframe = tasks.front();
    ASSERT_EQ(keyframe.kind, WriteTask::Kind::kKeyframe);
    EXPECT_EQ(keyframe.mapper_id, i);
    EXPECT_EQ(keyframe.record.session, SessionId(1));
    EXPECT_EQ(keyframe.record.color.size(), cv::Size(camera.width, camera.height));
    EXPECT_EQ(keyframe.record.depth.type(), CV_16UC1);
    EXPECT_EQ(keyframe.record.features.keypoints.size(), mapper.FeaturesOf(i).size());
    // A keyframe carries its own links, and a relocalisation it confirms carries the first one,
    // from the keyframe before it: links only ever reach keyframes already written.
    for (const slam::MapperLink& link : keyframe.links) {
      EXPECT_TRUE(link.to == i || link.from == i || link.type == LinkType::kRelocalisation)
          << "keyframe " << i << " carries " << link.from << " -> " << link.to;
      EXPECT_LE(std::max(link.from, link.to), i) << "a link to a keyframe not yet written";
    }
    if (i > 0 && mapper.SegmentOf(i) == mapper.SegmentOf(i - 1)) {
      EXPECT_FALSE(keyframe.links.empty()) << "keyframe " << i << " continues without a link";
    }
    for (size_t t = 1; t < tasks.size(); ++t) {
      if (tasks[t].kind == WriteTask::Kind::kPoses) {
        ++pose_updates;
        // Every pose after an optimisation of the whole map, the few a local one moved.
        EXPECT_FALSE(tasks[t].poses.empty());
        EXPECT_LE(tasks[t].poses.size(), static_cast<size_t>(i + 1));
        for (const auto& [id, pose] : tasks[t].poses) {
          EXPECT_TRUE(pose.isApprox(mapper.WorldFromCam(id), 0.0)) << id;
        }
      } else {
        ASSERT_EQ(tasks[t].kind, WriteTask::Kind::kVocabulary);
        EXPECT_FALSE(tasks[t].vocabulary.empty());
        ++vocabularies;
      }
    }
  }
  EXPECT_EQ(vocabularies, 1) << "the vocabulary is written once, when trained";
  EXPECT_EQ(stage.keyframes(), 34);
  EXPECT_EQ(stage.keyframe_seconds().size(), 34u);
  EXPECT_FALSE(stage.joined_stored_map());
  // Anchored: the first keyframe sits at its true pose, so the accuracy is in the scene's frame.
  EXPECT_TRUE(mapper.WorldFromCam(0).isApprox(truths.front().world_from_cam, 1e-9));
  const std::optional<slam::TrajectoryError> accuracy = stage.Accuracy();
  ASSERT_TRUE(accuracy.has_value());
  EXPECT_EQ(accuracy->matched_poses, 34);
  EXPECT_DOUBLE_EQ(accuracy->ate_rmse_m,
                   slam::EvaluateTrajectory(truths, mapper.Trajectory()).ate_rmse_m)
      << "this session's keyframes, each against its own ground truth";
  const WriteTask all = stage.AllPoses();
  EXPECT_EQ(all.kind, WriteTask::Kind::kPoses);
  EXPECT_EQ(all.poses.size(), 34u);
  // The last write: every pose after the whole map was optimised once more.
  const WriteTask last = stage.Finish();
  EXPECT_EQ(last.kind, WriteTask::Kind::kPoses);
  ASSERT_EQ(last.poses.size(), 34u);
  for (const auto& [id, pose] : last.poses) {
    EXPECT_TRUE(pose.isApprox(mapper.WorldFromCam(id), 0.0)) << id;
  }
  EXPECT_TRUE(last.deactivated.empty()) << "no loop of this walk is switched off";
}

// Tracked at 1 Hz, the walk goes blind for a second now and then (seed 11: frames 1-2, 9, 11);
// the keyframe that registers after such a run hands the writer the run's bridged prior links,
// as the mapper now holds them, to replace the stored guesses.
TEST(MapStage, AKeyframeAfterABlindRunHandsOverTheBridgedLinks) {
  sim::Simulator simulator = OneHzWalk(14);
  const Intrinsics camera = simulator.options().camera;
  slam::Tracker tracker(camera);
  slam::Mapper mapper(camera);
  MapStage stage(&mapper, SessionId(1), camera, MapStageOptions(), RestoredModel());
  std::map<int64_t, Eigen::Isometry3d> guessed;  // the motion model's step, by mapper id
  int revised = 0;
  for (int64_t i = 0; i < simulator.num_frames(); ++i) {
    for (slam::TrackedKeyframe& keyframe : tracker.Track(simulator.RenderFrame(i)).keyframes) {
      const auto id = static_cast<int64_t>(mapper.NumKeyframes());
      if (keyframe.motion && keyframe.motion->source == slam::MotionSource::kPrior) {
        guessed[id] = keyframe.motion->previous_from_cam;
      }
      KeyframeItem item;
      item.keyframe = std::move(keyframe);
      item.tracked = true;
      const WriteTask task = stage.Map(std::move(item)).front();
      for (const slam::MapperLink& link : task.revised) {
        ++revised;
        EXPECT_EQ(link.type, LinkType::kPrior);
        EXPECT_EQ(link.from + 1, link.to);
        EXPECT_LT(link.to, task.mapper_id) << "only links stored before";
        ASSERT_EQ(guessed.count(link.to), 1u) << "a link the motion model made";
        EXPECT_FALSE(link.to_in_from.isApprox(guessed[link.to], 1e-6)) << "bridged";
        const auto held = std::find_if(
            mapper.Links().begin(), mapper.Links().end(), [&link](const slam::MapperLink& l) {
              return l.from == link.from && l.to == link.to && l.type == link.type;
            });
        ASSERT_NE(held, mapper.Links().end());
        EXPECT_TRUE(held->to_in_from.isApprox(link.to_in_from, 0.0));
      }
    }
  }
  EXPECT_FALSE(guessed.empty()) << "the 1 Hz walk goes blind";
  EXPECT_GT(revised, 0);
}

TEST(MapStage, GroundTruthPosesNeedGroundTruthOnEveryKeyframe) {
  sim::Simulator simulator = OneHzWalk(2);
  const Intrinsics camera = simulator.options().camera;
  slam::Mapper mapper(camera);
  MapStageOptions options;
  options.ground_truth_poses = true;
  MapStage stage(&mapper, SessionId(1), camera, options, RestoredModel());
  RgbdFrame frame = simulator.RenderFrame(0);
  const Eigen::Isometry3d truth = *frame.world_from_cam_gt;
  stage.Map(Untracked(std::move(frame)));
  EXPECT_TRUE(mapper.WorldFromCam(0).isApprox(truth, 1e-9));
  RgbdFrame unknown = simulator.RenderFrame(1);
  unknown.world_from_cam_gt.reset();
  try {
    stage.Map(Untracked(std::move(unknown)));
    FAIL() << "a keyframe without ground truth was mapped";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--ground-truth-poses needs a source with ground truth"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(stage.keyframes(), 1);
}

TEST(MapStage, NoAccuracyWithoutGroundTruth) {
  sim::Simulator simulator = OneHzWalk(4);
  const Intrinsics camera = simulator.options().camera;
  slam::Mapper mapper(camera);
  MapStage stage(&mapper, SessionId(1), camera, MapStageOptions(), RestoredModel());
  for (int64_t i = 0; i < 4; ++i) {
    RgbdFrame frame = simulator.RenderFrame(i);
    if (i == 2) frame.world_from_cam_gt.reset();
    stage.Map(Untracked(std::move(frame)));
  }
  EXPECT_FALSE(stage.Accuracy().has_value()) << "one keyframe had no ground truth";
}

}  // namespace
}  // namespace sightmap::mapping
