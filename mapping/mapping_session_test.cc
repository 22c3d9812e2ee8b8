// The mapping session on the synthetic building, in process (the CLI tests run the binary): what
// reaches the model, how each stop reason ends the session, and a failing source.
#include "mapping/mapping_session.h"

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "mapping/source_testing.h"
#include "sim/sim_source.h"
#include "store/trajectory.h"
#include "tests/test_data.h"

namespace sightmap::mapping {
namespace {

// Frame 0 of the default (seed 1) walk faces a bare wall: the map starts on frame 1
// (slam::TrackerOptions::start_max_wait_s), so a walk of n frames at 1 Hz maps n - 1 keyframes.
constexpr int kBareStartFrames = 1;

MappingOptions SimOptions(const std::string& dir, int frames) {
  MappingOptions options;
  options.source = "sim:office?fps=1&frames=" + std::to_string(frames);
  options.model_path = dir + "/model.db";
  options.trajectory_path = dir + "/trajectory.txt";
  options.show_view = false;
  options.model.sync_every_commit = false;
  return options;
}

// Poses in a TUM trajectory file: its lines that are neither empty nor comments.
int CountPoses(const std::string& path) {
  std::ifstream in(path);
  int lines = 0;
  for (std::string line; std::getline(in, line);) lines += !line.empty() && line[0] != '#';
  return lines;
}

TEST(MappingSession, ASimWalkReachesTheModelKeyframeByKeyframe) {
  sim::RegisterSimSource();
  const std::string dir = testing::MakeTempDir("mapping-sim");
  MappingSession session(SimOptions(dir, 12));
  int64_t callbacks = 0;
  std::vector<std::string> ends;  // the calls that say mapping is ending, in order
  session.SetProgressCallback([&](const MappingProgress& progress) {
    ++callbacks;
    ASSERT_TRUE(progress.frames_total.has_value());
    EXPECT_EQ(*progress.frames_total, 12);
    if (progress.optimising_whole_map) ends.push_back("optimising");
    if (progress.finished) ends.push_back("finished");
  });
  const MappingSummary summary = session.Run();
  EXPECT_EQ(ends, (std::vector<std::string>{"optimising", "finished"}));
  EXPECT_GT(summary.final_optimisation_s, 0.0);
  EXPECT_EQ(summary.reason, StopReason::kSourceEnded);
  EXPECT_EQ(summary.frames_before_start, kBareStartFrames);
  const int keyframes = 12 - kBareStartFrames;
  EXPECT_EQ(summary.keyframes, keyframes);
  EXPECT_EQ(summary.frames_read, 12);
  EXPECT_EQ(summary.dropped_frames, 0) << "a replay waits, it never drops";
  EXPECT_GE(summary.segments, 1);
  EXPECT_FALSE(summary.resumed);
  EXPECT_GE(callbacks, keyframes);
  // How well the mapper tracks a 1 Hz walk is slam_benchmark's business; here the ATE must exist
  // and be computed over every keyframe.
  ASSERT_TRUE(summary.ate_rmse_m.has_value());
  EXPECT_EQ(summary.ate_poses, keyframes);
  EXPECT_TRUE(std::isfinite(*summary.ate_rmse_m));

  const store::Model model = store::Model::Open(dir + "/model.db", store::ModelOptions::ReadOnly());
  EXPECT_EQ(model.NumKeyframes(), keyframes);
  const std::vector<store::SessionRecord> sessions = model.Sessions();
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_EQ(sessions[0].end_state, store::SessionEnd::kFinished);
  EXPECT_EQ(sessions[0].source, "sim:office?fps=1&frames=12");
  // Every link reached the store: the model's graph falls into the mapper's segments.
  EXPECT_EQ(model.Summary().segments, summary.segments);
  EXPECT_EQ(model.Summary().largest_segment_keyframes, summary.largest_segment_keyframes);
  EXPECT_GE(summary.largest_segment_keyframes * summary.segments, summary.model_keyframes);
  EXPECT_FALSE(model.Links().empty());
  EXPECT_EQ(model.LoadFeatures(model.Keyframes().back().id).keypoints.size(),
            static_cast<size_t>(model.Keyframes().back().num_features));
  // The trajectory file holds the model's (final) poses.
  const std::vector<StampedPose> written = ReadTumTrajectory(dir + "/trajectory.txt");
  const std::vector<StampedPose> stored = store::ModelTrajectory(model);
  ASSERT_EQ(written.size(), static_cast<size_t>(keyframes));
  ASSERT_EQ(stored.size(), static_cast<size_t>(keyframes));
  for (size_t i = 0; i < stored.size(); ++i) {
    EXPECT_EQ(written[i].timestamp_ns, stored[i].timestamp_ns);
    EXPECT_LT(
        (written[i].world_from_cam.translation() - stored[i].world_from_cam.translation()).norm(),
        1e-6);
  }
  EXPECT_EQ(model.IntegrityCheck(), "ok");
}

TEST(MappingSession, AnInterruptFinishesTheKeyframeInHandAndEndsTheSession) {
  sim::RegisterSimSource();
  const std::string dir = testing::MakeTempDir("mapping-interrupt");
  MappingOptions options = SimOptions(dir, 40);
  options.ply_path = dir + "/model.ply";
  MappingSession session(options);
  std::atomic<bool> interrupt{false};
  session.SetInterruptFlag(&interrupt);
  session.SetProgressCallback([&](const MappingProgress& progress) {
    if (progress.keyframes >= 3) interrupt = true;
  });
  const MappingSummary summary = session.Run();
  EXPECT_EQ(summary.reason, StopReason::kSignal);
  EXPECT_EQ(summary.keyframes, 3);
  EXPECT_LT(summary.frames_read, 40);
  EXPECT_GT(summary.ply_points, 1000);
  const store::Model model = store::Model::Open(dir + "/model.db", store::ModelOptions::ReadOnly());
  EXPECT_EQ(model.NumKeyframes(), 3);
  EXPECT_EQ(model.Sessions().at(0).end_state, store::SessionEnd::kFinished);
  EXPECT_TRUE(std::filesystem::file_size(dir + "/model.ply") > 0);
}

TEST(MappingSession, AnUnpluggedSensorEndsGracefullyWithTheReason) {
  capture::RegisterSourceOpener(capture::SourceSpec::Kind::kSim,
                                [](const std::string& location, const capture::SourceOptions&) {
                                  return std::make_unique<testing::FailingSource>(
                                      sim::OpenSimSource(sim::ParseSimLocation(location)), 5);
                                });
  const std::string dir = testing::MakeTempDir("mapping-unplugged");
  MappingSession session(SimOptions(dir, 20));
  const MappingSummary summary = session.Run();
  sim::RegisterSimSource();
  EXPECT_EQ(summary.reason, StopReason::kSourceFailed);
  EXPECT_NE(summary.reason_detail.find("unplugged"), std::string::npos) << summary.reason_detail;
  // The five frames delivered before the failure, each a keyframe at 1 Hz once the map started.
  const int keyframes = 5 - kBareStartFrames;
  EXPECT_EQ(summary.keyframes, keyframes);
  const store::Model model = store::Model::Open(dir + "/model.db", store::ModelOptions::ReadOnly());
  EXPECT_EQ(model.NumKeyframes(), keyframes);
  EXPECT_EQ(model.Sessions().at(0).end_state, store::SessionEnd::kInterrupted);
  EXPECT_EQ(CountPoses(dir + "/trajectory.txt"), keyframes);
}

// Killed halfway and run again with the same command, a replay continues after its last stored
// frame instead of mapping the walk twice; once it is all in, a further run says so.
TEST(MappingSession, AResumedReplayContinuesAfterItsLastStoredFrame) {
  sim::RegisterSimSource();
  const std::string dir = testing::MakeTempDir("mapping-continue");
  MappingOptions first = SimOptions(dir, 20);
  first.max_keyframes = 8;
  ASSERT_EQ(MappingSession(first).Run().keyframes, 8);
  const int last_stored = 8 + kBareStartFrames - 1;  // frames 1-8 at 1 Hz

  const MappingSummary second = MappingSession(SimOptions(dir, 20)).Run();
  EXPECT_TRUE(second.resumed);
  ASSERT_TRUE(second.continued_after_s.has_value());
  EXPECT_NEAR(*second.continued_after_s, last_stored, 1e-6);
  EXPECT_EQ(second.frames_skipped, last_stored + 1);
  EXPECT_EQ(second.frames_read, 20);
  EXPECT_EQ(second.frames_before_start, 0) << "a continued walk starts on its stored keyframe";
  EXPECT_EQ(second.keyframes, 20 - (last_stored + 1));
  {
    const store::Model model =
        store::Model::Open(dir + "/model.db", store::ModelOptions::ReadOnly());
    std::set<TimestampNs> stamps;
    for (const store::KeyframeInfo& keyframe : model.Keyframes())
      stamps.insert(keyframe.timestamp_ns);
    EXPECT_EQ(model.NumKeyframes(), 20 - kBareStartFrames);
    EXPECT_EQ(stamps.size(), static_cast<size_t>(model.NumKeyframes()))
        << "a frame was mapped twice";
  }

  try {
    MappingSession(SimOptions(dir, 20)).Run();
    FAIL() << "a third run of a walk that is all in the model reported success";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nothing left to map"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--start-frame 0"), std::string::npos) << e.what();
  }
  // Another walk (another SOURCE string) into the same model starts from its frame 0.
  const MappingSummary other = MappingSession(SimOptions(dir, 3)).Run();
  EXPECT_FALSE(other.continued_after_s.has_value());
  EXPECT_EQ(other.frames_skipped, 0);
  EXPECT_EQ(other.keyframes, 3 - kBareStartFrames);
}

TEST(MappingSession, AStartFramePastTheEndIsRefusedBeforeTheModelIsTouched) {
  sim::RegisterSimSource();
  const std::string dir = testing::MakeTempDir("mapping-start-past-end");
  MappingOptions options = SimOptions(dir, 10);
  options.start_frame = 10;
  options.continue_replay = false;
  try {
    MappingSession(options).Run();
    FAIL() << "mapped nothing and reported success";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("past the end"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("10 frames"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/model.db"));
  options.start_frame = 9;  // the last frame is still a walk of one keyframe
  EXPECT_EQ(MappingSession(options).Run().keyframes, 1);
}

TEST(MappingSession, BadOptionsAreRefused) {
  MappingOptions options;
  options.source = "sim:office";
  EXPECT_THROW(MappingSession{options}, InvalidArgument);  // no model
  options.model_path = "x.db";
  options.frame_queue_capacity = 0;
  EXPECT_THROW(MappingSession{options}, InvalidArgument);
  options.frame_queue_capacity = 2;
  options.keyframe_queue_capacity = 0;
  EXPECT_THROW(MappingSession{options}, InvalidArgument);
  options.keyframe_queue_capacity = 2;
  options.track_every = 0;
  EXPECT_THROW(MappingSession{options}, InvalidArgument);
  options.track_every = 1;
  options.replay_nice_increment = 20;
  EXPECT_THROW(MappingSession{options}, InvalidArgument);
  options.replay_nice_increment = 10;
  options.replay_write_nice_increment = -1;
  EXPECT_THROW(MappingSession{options}, InvalidArgument);
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "replay_write_nice_increment must be in [0, 19]");
}

}  // namespace
}  // namespace sightmap::mapping
