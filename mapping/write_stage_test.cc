// The writing stage against a real model file: keyframes and links reach it with the model's ids,
// pose updates switch stored links off, a keyframe's revisions replace older links, the vocabulary
// is stored, the view draws the loops the model holds, and a failed write stops the stage without
// losing what was committed.
#include "mapping/write_stage.h"

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/thread_priority.h"
#include "tests/test_data.h"

namespace sightmap::mapping {
namespace {

Intrinsics SmallCamera() {
  Intrinsics camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 50.0;
  camera.cx = 31.5;
  camera.cy = 23.5;
  return camera;
}

Eigen::Isometry3d At(double x) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(x, 0.0, 0.0);
  return pose;
}

slam::MapperLink Link(int64_t from, int64_t to, LinkType type) {
  slam::MapperLink link;
  link.from = from;
  link.to = to;
  link.type = type;
  link.to_in_from = At(static_cast<double>(to - from));
  return link;
}

WriteTask KeyframeTask(SessionId session, int64_t mapper_id, std::vector<slam::MapperLink> links) {
  WriteTask task;
  task.kind = WriteTask::Kind::kKeyframe;
  task.mapper_id = mapper_id;
  task.record.session = session;
  task.record.timestamp_ns = 1'000'000'000 * (mapper_id + 1);
  task.record.world_from_cam = At(static_cast<double>(mapper_id));
  task.record.odom_world_from_cam = task.record.world_from_cam;
  task.record.intrinsics = SmallCamera();
  task.record.color = cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 30));
  task.record.depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(1500));
  task.links = std::move(links);
  return task;
}

SessionId Begin(store::Model& model) {
  store::SessionRecord record;
  record.source = "test";
  record.intrinsics = SmallCamera();
  return model.BeginSession(record);
}

// Photo features are the writer's work: each keyframe is stored with RootSIFT features and their
// points, taken from its own colour and depth (downscaled when larger than max_side_px).
TEST(WriteStage, KeyframesAreWrittenWithTheirPhotoFeatures) {
  const std::string path = testing::MakeTempDir("write-stage-photo") + "/model.db";
  store::Model model = store::Model::Open(path);
  const SessionId session = Begin(model);
  PhotoFeatureExtraction extraction;
  extraction.features.type = slam::FeatureOptions::Type::kSift;
  extraction.max_side_px = 320;
  WriteTask task = KeyframeTask(session, 0, {});
  task.record.intrinsics = SmallCamera().Scaled(640, 480);
  task.record.color = cv::Mat(480, 640, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::RNG rng(3);
  for (int i = 0; i < 300; ++i) {
    const cv::Point centre(rng.uniform(0, 640), rng.uniform(0, 480));
    cv::circle(task.record.color, centre, rng.uniform(3, 20), cv::Scalar::all(rng.uniform(0, 256)),
               cv::FILLED);
  }
  task.record.depth = cv::Mat(480, 640, CV_16UC1, cv::Scalar(1500));
  {
    WriteStage stage(&model, nullptr, 1, {}, 2, extraction);
    ASSERT_TRUE(stage.Push(task));
    ASSERT_TRUE(stage.Push(KeyframeTask(session, 1, {})));  // blank: none found
    stage.Finish();
    ASSERT_FALSE(stage.failed());
  }
  const std::vector<store::KeyframeInfo> infos = model.Keyframes();
  ASSERT_EQ(infos.size(), 2u);
  const std::optional<Features> stored = model.LoadPhotoFeatures(infos[0].id);
  ASSERT_TRUE(stored.has_value());
  EXPECT_GT(stored->size(), 50u);
  EXPECT_EQ(stored->descriptors.cols, 128);
  EXPECT_EQ(stored->NumPoints(), stored->size());
  for (const cv::KeyPoint& keypoint : stored->keypoints) {
    EXPECT_LT(keypoint.pt.x, 320.0f);  // found on the 320x240 copy
  }
  for (const Eigen::Vector3d& point : stored->points_cam) EXPECT_NEAR(point.z(), 1.5, 1e-9);
  // The blank keyframe's empty row says they were looked for: nobody extracts them again.
  ASSERT_TRUE(model.LoadPhotoFeatures(infos[1].id).has_value());
  EXPECT_EQ(model.LoadPhotoFeatures(infos[1].id)->size(), 0u);
  EXPECT_EQ(AddMissingPhotoFeatures(&model, extraction), 0);
}

TEST(WriteStage, KeyframesLinksPosesAndTheVocabularyReachTheModelWithItsIds) {
  const std::string path = testing::MakeTempDir("write-stage") + "/model.db";
  {
    store::Model model = store::Model::Open(path);
    const SessionId session = Begin(model);
    WriteStage stage(&model, nullptr, 1, {}, 2);
    ASSERT_TRUE(stage.Push(KeyframeTask(session, 0, {})));
    ASSERT_TRUE(stage.Push(KeyframeTask(session, 1, {Link(0, 1, LinkType::kOdometry)})));
    ASSERT_TRUE(stage.Push(KeyframeTask(
        session, 2, {Link(1, 2, LinkType::kPrior), Link(0, 2, LinkType::kLoopClosure)})));
    WriteTask poses;
    poses.kind = WriteTask::Kind::kPoses;
    poses.poses = {{0, At(0.5)}, {2, At(2.5)}, {7, At(7.0)}};  // 7 is not written yet: skipped
    poses.deactivated = {Link(0, 2, LinkType::kLoopClosure)};
    ASSERT_TRUE(stage.Push(poses));
    WriteTask vocabulary;
    vocabulary.kind = WriteTask::Kind::kVocabulary;
    vocabulary.vocabulary = {1, 2, 3};
    ASSERT_TRUE(stage.Push(vocabulary));
    // Keyframe 3 measured the motion after the blind keyframe 2: the prior 1 -> 2 is bridged.
    WriteTask after_blind = KeyframeTask(session, 3, {Link(2, 3, LinkType::kOdometry)});
    slam::MapperLink bridged = Link(1, 2, LinkType::kPrior);
    bridged.to_in_from = At(0.7);
    bridged.information = 4.0 * Matrix6d::Identity();
    after_blind.revised = {bridged};
    ASSERT_TRUE(stage.Push(after_blind));
    stage.Finish();
    EXPECT_FALSE(stage.failed());
    EXPECT_EQ(stage.committed(), 4);
  }
  store::ModelOptions read_only;
  read_only.read_only = true;
  const store::Model model = store::Model::Open(path, read_only);
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  ASSERT_EQ(keyframes.size(), 4u);
  EXPECT_NEAR(keyframes[0].world_from_cam.translation().x(), 0.5, 1e-9);
  EXPECT_NEAR(keyframes[1].world_from_cam.translation().x(), 1.0, 1e-9);
  EXPECT_NEAR(keyframes[2].world_from_cam.translation().x(), 2.5, 1e-9);
  const std::vector<store::LinkRecord> links = model.Links();
  ASSERT_EQ(links.size(), 4u);
  int loops = 0;
  for (const store::LinkRecord& link : links) {
    if (link.type == LinkType::kLoopClosure) {
      ++loops;
      EXPECT_EQ(link.from, keyframes[0].id);
      EXPECT_EQ(link.to, keyframes[2].id);
      EXPECT_FALSE(link.active) << "switched off by the pose update";
    } else if (link.type == LinkType::kPrior) {
      EXPECT_EQ(link.from, keyframes[1].id);
      EXPECT_EQ(link.to, keyframes[2].id);
      EXPECT_TRUE(link.active);
      EXPECT_NEAR(link.to_in_from.translation().x(), 0.7, 1e-12) << "revised by keyframe 3";
      EXPECT_EQ(link.information(0, 0), 4.0);
    } else {
      EXPECT_EQ(link.type, LinkType::kOdometry);
      EXPECT_EQ(link.to.value() - link.from.value(), 1);
    }
  }
  EXPECT_EQ(loops, 1);
  const auto vocabulary = model.LoadVocabulary();
  ASSERT_TRUE(vocabulary.has_value());
  EXPECT_EQ(vocabulary->second, (std::vector<uint8_t>{1, 2, 3}));
}

TEST(WriteStage, LinksToRestoredKeyframesUseTheirModelIds) {
  const std::string path = testing::MakeTempDir("write-stage-restored") + "/model.db";
  store::Model model = store::Model::Open(path);
  const SessionId first = Begin(model);
  std::vector<KeyframeId> restored;
  {
    WriteStage stage(&model, nullptr, 1, {}, 2);
    stage.Push(KeyframeTask(first, 0, {}));
    stage.Push(KeyframeTask(first, 1, {Link(0, 1, LinkType::kOdometry)}));
    stage.Finish();
  }
  for (const store::KeyframeInfo& info : model.Keyframes()) restored.push_back(info.id);
  const SessionId second = Begin(model);
  WriteStage stage(&model, nullptr, 2, restored, 2);
  stage.Push(KeyframeTask(second, 2, {Link(1, 2, LinkType::kRelocalisation)}));
  stage.Finish();
  ASSERT_FALSE(stage.failed());
  const std::vector<store::LinkRecord> links = model.Links();
  ASSERT_EQ(links.size(), 2u);
  EXPECT_EQ(links[1].type, LinkType::kRelocalisation);
  EXPECT_EQ(links[1].from, restored[1]);
  EXPECT_EQ(links[1].to, model.Keyframes().back().id);
}

// Magenta pixels (the loops' colour, render/map_renderer.cc) of the floor plan, the progress
// image's left half.
int LoopPixels(const std::string& progress_png) {
  const cv::Mat image = cv::imread(progress_png);
  EXPECT_FALSE(image.empty()) << progress_png;
  if (image.empty()) return -1;
  cv::Mat near;
  cv::inRange(image(cv::Rect(0, 0, image.cols / 2, image.rows)), cv::Scalar(210, 44, 235),
              cv::Scalar(250, 84, 255), near);
  return cv::countNonZero(near);
}

// The view shows the loops the model holds: a stored loop the optimiser switches off leaves the
// floor plan, one switched back on returns; a blind run's prior is never drawn as a loop.
TEST(WriteStage, TheViewDrawsTheLoopsThePoseUpdatesLeaveOn) {
  const std::string folder = testing::MakeTempDir("write-stage-view");
  store::Model model = store::Model::Open(folder + "/model.db");
  const SessionId session = Begin(model);
  const auto loop_pixels_after = [&](const std::string& name,
                                     const std::vector<WriteTask>& updates) {
    MapViewFeedOptions options;
    options.choice = ViewChoice::kHeadless;
    options.progress_png = folder + "/" + name + ".png";
    std::unique_ptr<MapViewFeed> feed = MapViewFeed::Create(options, nullptr);
    WriteStage stage(&model, feed.get(), 1, {}, 8);
    // A right angle: 1 m along x, then 1 m along z; the loop joins its ends.
    WriteTask corner = KeyframeTask(
        session, 2, {Link(1, 2, LinkType::kPrior), Link(0, 2, LinkType::kLoopClosure)});
    corner.record.world_from_cam = Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.0, 1.0));
    EXPECT_TRUE(stage.Push(KeyframeTask(session, 0, {})));
    EXPECT_TRUE(stage.Push(KeyframeTask(session, 1, {Link(0, 1, LinkType::kOdometry)})));
    EXPECT_TRUE(stage.Push(corner));
    for (const WriteTask& update : updates) EXPECT_TRUE(stage.Push(update));
    stage.Finish();
    EXPECT_FALSE(stage.failed());
    feed->Finish();
    return LoopPixels(options.progress_png);
  };
  WriteTask off;
  off.kind = WriteTask::Kind::kPoses;
  off.deactivated = {Link(0, 2, LinkType::kLoopClosure)};
  WriteTask on = off;
  on.deactivated.clear();
  on.reactivated = {Link(0, 2, LinkType::kLoopClosure)};
  EXPECT_GT(loop_pixels_after("drawn", {}), 30);
  EXPECT_EQ(loop_pixels_after("off", {off}), 0);
  EXPECT_GT(loop_pixels_after("back_on", {off, on}), 30);
}

// A replay's writer runs at a lower priority than the stage that starts it; the starter keeps its
// own, and an increment outside nice's range is refused.
TEST(WriteStage, ItsThreadRunsTheGivenIncrementLower) {
  const std::string path = testing::MakeTempDir("write-stage-nice") + "/model.db";
  store::Model model = store::Model::Open(path);
  const SessionId session = Begin(model);
  const int base = ThisThreadsNice();
  for (const int increment : {0, 3}) {
    WriteStage stage(&model, nullptr, 1, {}, 2, std::nullopt, increment);
    stage.Push(KeyframeTask(session, 0, {}));
    stage.Finish();
    ASSERT_FALSE(stage.failed());
    EXPECT_EQ(stage.thread_nice(), std::min(19, base + increment)) << "increment " << increment;
  }
  EXPECT_EQ(ThisThreadsNice(), base);
  EXPECT_THROW(WriteStage(&model, nullptr, 1, {}, 2, std::nullopt, 20), Error);
}

TEST(WriteStage, AFailedWriteStopsTheStageAndKeepsWhatWasCommitted) {
  const std::string path = testing::MakeTempDir("write-stage-failure") + "/model.db";
  store::Model model = store::Model::Open(path);
  const SessionId session = Begin(model);
  WriteStage stage(&model, nullptr, 1, {}, 4);
  ASSERT_TRUE(stage.Push(KeyframeTask(session, 0, {})));
  ASSERT_TRUE(stage.Push(KeyframeTask(session, 5, {})));  // out of order: a bug upstream
  while (!stage.failed()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_FALSE(stage.Push(KeyframeTask(session, 1, {}))) << "refused once failed";
  stage.Finish();
  ASSERT_NE(stage.error(), nullptr);
  try {
    std::rethrow_exception(stage.error());
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out of order"), std::string::npos) << e.what();
  }
  EXPECT_EQ(stage.committed(), 1);
  EXPECT_EQ(model.NumKeyframes(), 1);
  EXPECT_EQ(model.IntegrityCheck(), "ok");
}

}  // namespace
}  // namespace sightmap::mapping
