// Restoring a mapped model into a new Mapper: every keyframe, link, pose and the vocabulary as
// stored, the camera checked, and a new session that walks the same places joins the stored map.
#include "mapping/model_restore.h"

#include <algorithm>
#include <string>

#include <gtest/gtest.h>

#include "mapping/map_stage.h"
#include "mapping/mapping_session.h"
#include "sim/sim_source.h"
#include "sim/simulator.h"
#include "tests/test_data.h"

namespace sightmap::mapping {
namespace {

constexpr int kStoredKeyframes = 36;  // past the 30 the vocabulary is trained on

// A model of the first kStoredKeyframes seconds of the 1 Hz walk (seed 11), made once.
const std::string& StoredModel() {
  static const std::string path = [] {
    sim::RegisterSimSource();
    const std::string dir = testing::MakeTempDir("model-restore");
    MappingOptions options;
    options.source = "sim:office?fps=1&seed=11&frames=" + std::to_string(kStoredKeyframes);
    options.model_path = dir + "/model.db";
    options.show_view = false;
    options.model.sync_every_commit = false;
    MappingSession(options).Run();
    return options.model_path;
  }();
  return path;
}

store::Model OpenReadOnly(const std::string& path) {
  store::ModelOptions options;
  options.read_only = true;
  return store::Model::Open(path, options);
}

sim::SimulatorOptions WalkOptions() {
  sim::SimulatorOptions options;
  options.fps = 1.0;
  options.seed = 11;
  options.frames = kStoredKeyframes;
  return options;
}

TEST(RestoreModel, TheMapperGetsEveryKeyframeLinkPoseAndTheVocabulary) {
  const store::Model model = OpenReadOnly(StoredModel());
  const Intrinsics camera = WalkOptions().camera;
  slam::Mapper mapper(camera);
  const RestoredModel restored = RestoreModel(model, camera, true, &mapper, nullptr);
  const std::vector<store::KeyframeInfo> stored = model.Keyframes();
  ASSERT_EQ(stored.size(), static_cast<size_t>(kStoredKeyframes));
  ASSERT_EQ(restored.store_ids.size(), stored.size());
  EXPECT_EQ(mapper.NumKeyframes(), stored.size());
  for (size_t i = 0; i < stored.size(); ++i) {
    EXPECT_EQ(restored.store_ids[i], stored[i].id);
    EXPECT_TRUE(
        mapper.WorldFromCam(static_cast<int64_t>(i)).isApprox(stored[i].world_from_cam, 1e-12));
    EXPECT_EQ(mapper.FeaturesOf(static_cast<int64_t>(i)).size(),
              static_cast<size_t>(stored[i].num_features));
  }
  EXPECT_EQ(mapper.Links().size(), model.Links().size());
  EXPECT_TRUE(restored.vocabulary_restored);
  ASSERT_NE(mapper.vocabulary(), nullptr);
  EXPECT_EQ(static_cast<int64_t>(restored.segment_members.size()), model.Summary().segments);
  EXPECT_EQ(static_cast<int>(restored.segment_members.size()), mapper.NumSegments());
  // The newest keyframe as a frame, for a tracker that continues its walk.
  const RgbdFrame newest = NewestKeyframeFrame(model, restored);
  EXPECT_EQ(newest.timestamp_ns, stored.back().timestamp_ns);
  EXPECT_EQ(newest.color.type(), CV_8UC3);
  EXPECT_EQ(newest.color.size(), cv::Size(camera.width, camera.height));
  EXPECT_EQ(cv::norm(newest.depth, model.LoadDepth(stored.back().id), cv::NORM_INF), 0.0);
  EXPECT_THROW(NewestKeyframeFrame(model, RestoredModel()), Error);
}

TEST(RestoreModel, AnotherCameraSizeIsRefusedWithWhatToDo) {
  const store::Model model = OpenReadOnly(StoredModel());
  Intrinsics camera = WalkOptions().camera;
  camera.width /= 2;
  camera.height /= 2;
  slam::Mapper mapper(camera);
  try {
    RestoreModel(model, camera, false, &mapper, nullptr);
    FAIL() << "a model of another camera size was restored";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("map into a new model"), std::string::npos) << e.what();
  }
}

TEST(RestoreModel, ANewSessionWalkingTheSamePlacesJoinsTheStoredMap) {
  const store::Model model = OpenReadOnly(StoredModel());
  const Intrinsics camera = WalkOptions().camera;
  slam::Mapper mapper(camera);
  const RestoredModel restored = RestoreModel(model, camera, true, &mapper, nullptr);
  MapStage stage(&mapper, SessionId(2), camera, MapStageOptions(), restored);
  sim::Simulator simulator(WalkOptions());
  for (int64_t i = 0; i < 12; ++i) {
    KeyframeItem item;
    item.keyframe.frame = simulator.RenderFrame(i);
    const std::vector<WriteTask> tasks = stage.Map(std::move(item));
    for (const WriteTask& task : tasks) {
      EXPECT_NE(task.kind, WriteTask::Kind::kVocabulary) << "the model has one already";
    }
  }
  EXPECT_TRUE(stage.joined_stored_map());
  int relocalisations = 0;  // from a stored keyframe to a new one
  for (const slam::MapperLink& link : mapper.Links()) {
    relocalisations += link.type == LinkType::kRelocalisation &&
                       std::min(link.from, link.to) < kStoredKeyframes &&
                       std::max(link.from, link.to) >= kStoredKeyframes;
  }
  EXPECT_GE(relocalisations, 1);
}

}  // namespace
}  // namespace sightmap::mapping
