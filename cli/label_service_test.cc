#include "cli/label_service.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "store/synthetic_model.h"
#include "tests/test_data.h"

namespace sightmap::cli {
namespace {

// Two keyframes of the synthetic wall (2 m away) in one session, in a model file.
class LabelServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = testing::MakeTempDir("label_service") + "/model.db";
    store::Model model = store::Model::Open(path_);
    store::SessionRecord session;
    session.source = "sim:office";
    const SessionId id = model.BeginSession(session);
    store::SyntheticKeyframeOptions options;
    options.width = 320;
    options.height = 240;
    options.num_features = 20;
    for (int i = 0; i < 2; ++i)
      keyframes_.push_back(model.AddKeyframe(store::MakeSyntheticKeyframe(id, i, options)));
  }

  LabelService Service(bool editable = true) {
    LabelServiceOptions options;
    options.editable = editable;
    options.read_only_reason = "started with --read-only";
    return LabelService(path_, options, [this](const store::Model& model) {
      ++reloads_;
      reloaded_labels_ = model.Labels().size();
    });
  }

  // The status a call is refused with (0 when it is not).
  template <typename Call>
  static int RefusedWith(Call call) {
    try {
      call();
    } catch (const ServiceError& e) {
      EXPECT_FALSE(std::string(e.what()).empty());
      return e.status();
    }
    return 0;
  }

  std::string path_;
  std::vector<KeyframeId> keyframes_;
  int reloads_ = 0;
  size_t reloaded_labels_ = 0;
};

TEST_F(LabelServiceTest, ListsSessionsKeyframesAndTheirImages) {
  LabelService service = Service();
  const nlohmann::json status = service.Status();
  EXPECT_TRUE(status.at("editable").get<bool>());
  EXPECT_EQ(status.at("keyframes"), 2);
  EXPECT_EQ(status.at("labels"), 0);

  const nlohmann::json listed = service.Keyframes();
  ASSERT_EQ(listed.at("sessions").size(), 1u);
  EXPECT_EQ(listed["sessions"][0].at("number"), 1);
  EXPECT_EQ(listed["sessions"][0].at("keyframes"), 2);
  ASSERT_EQ(listed.at("keyframes").size(), 2u);
  EXPECT_EQ(listed["keyframes"][0].at("id"), keyframes_[0].value());
  EXPECT_DOUBLE_EQ(listed["keyframes"][0].at("time_s").get<double>(), 0.0);
  EXPECT_GT(listed["keyframes"][1].at("time_s").get<double>(), 0.0);
  EXPECT_EQ(listed["keyframes"][1].at("width"), 320);

  const std::string full = service.KeyframeJpeg(keyframes_[0].value(), 0);
  const cv::Mat image =
      cv::imdecode(std::vector<uint8_t>(full.begin(), full.end()), cv::IMREAD_COLOR);
  EXPECT_EQ(image.size(), cv::Size(320, 240));
  const std::string thumb = service.KeyframeJpeg(keyframes_[0].value(), 160);
  const cv::Mat small =
      cv::imdecode(std::vector<uint8_t>(thumb.begin(), thumb.end()), cv::IMREAD_COLOR);
  EXPECT_EQ(small.size(), cv::Size(160, 120));
  EXPECT_EQ(RefusedWith([&] { service.KeyframeJpeg(99, 0); }), 404);
  EXPECT_EQ(RefusedWith([&] { service.KeyframeJpeg(keyframes_[0].value(), 5000); }), 400);
}

TEST_F(LabelServiceTest, AClickedPixelBecomesTheSamePointAsLabelAdd) {
  LabelService service = Service();
  const nlohmann::json added = service.AddPoint({{"name", "projector 1"},
                                                 {"type", "projector"},
                                                 {"keyframe", keyframes_[1].value()},
                                                 {"pixel", {200, 100}}});
  EXPECT_TRUE(added.at("created").get<bool>());
  EXPECT_EQ(reloads_, 1);
  EXPECT_EQ(reloaded_labels_, 1u);
  EXPECT_NE(added.at("message").get<std::string>().find("created 'projector 1' (projector)"),
            std::string::npos)
      << added.at("message");
  // The same code as `sightmap label add --keyframe 2 --pixel 200,100`.
  const store::Model model = store::Model::Open(path_, store::ModelOptions::ReadOnly());
  const identify::PixelLabelPoint expected =
      identify::LabelPointFromPixel(model, keyframes_[1], Eigen::Vector2d(200, 100));
  const nlohmann::json& world = added.at("point").at("world");
  EXPECT_NEAR(world[0].get<double>(), expected.point.world.x(), 1e-9);
  EXPECT_NEAR(world[1].get<double>(), expected.point.world.y(), 1e-9);
  EXPECT_NEAR(world[2].get<double>(), expected.point.world.z(), 1e-9);
  EXPECT_NEAR(added.at("point").at("depth_m").get<double>(), 2.0, 0.01);
  const std::optional<store::LabelRecord> stored = model.FindLabel("projector 1");
  ASSERT_TRUE(stored);
  ASSERT_EQ(stored->points.size(), 1u);
  EXPECT_EQ(stored->points[0].source, store::LabelPointSource::kKeyframePixel);
  EXPECT_EQ(stored->points[0].pixel, Eigen::Vector2d(200, 100));

  // A second point to the same name keeps its type; the label is drawn on both keyframes.
  const nlohmann::json again = service.AddPoint(
      {{"name", "projector 1"}, {"keyframe", keyframes_[0].value()}, {"pixel", {160, 120}}});
  EXPECT_FALSE(again.at("created").get<bool>());
  EXPECT_EQ(again.at("label").at("type"), "projector");
  EXPECT_EQ(again.at("label").at("points").size(), 2u);
  const nlohmann::json drawn = service.KeyframeLabels(keyframes_[1].value());
  ASSERT_EQ(drawn.at("labels").size(), 1u);
  const nlohmann::json& point = drawn["labels"][0]["points"][0];
  EXPECT_NEAR(point.at("pixel")[0].get<double>(), 200.0, 1e-6);
  EXPECT_NEAR(point.at("pixel")[1].get<double>(), 100.0, 1e-6);
  EXPECT_FALSE(point.at("hidden").get<bool>());
  const nlohmann::json labels = service.Labels();
  ASSERT_EQ(labels.at("labels").size(), 1u);
  EXPECT_EQ(labels["labels"][0].at("seen_by").size(), 2u);
}

TEST_F(LabelServiceTest, BadEditsAreRefusedWithTheirStatusAndChangeNothing) {
  LabelService service = Service();
  const int64_t keyframe = keyframes_[0].value();
  EXPECT_EQ(RefusedWith([&] {
              service.AddPoint({{"keyframe", keyframe}, {"pixel", {1, 1}}});
            }),
            400);
  EXPECT_EQ(RefusedWith([&] {
              service.AddPoint({{"name", "a\nb"}, {"keyframe", keyframe}, {"pixel", {1, 1}}});
            }),
            400);
  EXPECT_EQ(RefusedWith([&] {
              service.AddPoint({{"name", "lamp"}, {"keyframe", keyframe}, {"pixel", {-5, 1}}});
            }),
            400);
  EXPECT_EQ(RefusedWith([&] {
              service.AddPoint({{"name", "lamp"}, {"keyframe", 77}, {"pixel", {1, 1}}});
            }),
            404);
  EXPECT_EQ(RefusedWith([&] { service.AddPoint(nlohmann::json::array()); }), 400);
  EXPECT_EQ(RefusedWith([&] {
              service.AddPoint({{"name", "lamp"}, {"keyframe", "1"}, {"pixel", {1, 1}}});
            }),
            400);
  EXPECT_EQ(reloads_, 0);
  EXPECT_EQ(store::Model::Open(path_, store::ModelOptions::ReadOnly()).Labels().size(), 0u);

  service.AddPoint({{"name", "lamp"}, {"keyframe", keyframe}, {"pixel", {10, 10}}});
  service.AddPoint({{"name", "fan"}, {"keyframe", keyframe}, {"pixel", {20, 10}}});
  const int64_t lamp =
      store::Model::Open(path_, store::ModelOptions::ReadOnly()).FindLabel("lamp")->id.value();
  EXPECT_EQ(RefusedWith([&] { service.Edit(lamp, {{"name", "fan"}}); }), 409);
  EXPECT_EQ(RefusedWith([&] { service.Edit(lamp, nlohmann::json::object()); }), 400);
  EXPECT_EQ(RefusedWith([&] { service.Edit(lamp + 100, {{"type", "x"}}); }), 404);
  EXPECT_EQ(RefusedWith([&] { service.Remove(lamp + 100); }), 404);

  const nlohmann::json renamed = service.Edit(lamp, {{"name", "desk lamp"}, {"type", "lamp"}});
  EXPECT_EQ(renamed.at("label").at("name"), "desk lamp");
  EXPECT_EQ(renamed.at("label").at("type"), "lamp");
  EXPECT_EQ(renamed.at("label").at("points").size(), 1u) << "renaming keeps the points";
  EXPECT_EQ(service.Remove(lamp).at("removed"), "desk lamp");
  const std::vector<store::LabelRecord> left =
      store::Model::Open(path_, store::ModelOptions::ReadOnly()).Labels();
  ASSERT_EQ(left.size(), 1u);
  EXPECT_EQ(left[0].name, "fan");
}

TEST_F(LabelServiceTest, AReadOnlyServiceShowsButRefusesEveryWriteWith403) {
  Service().AddPoint({{"name", "lamp"}, {"keyframe", keyframes_[0].value()}, {"pixel", {5, 5}}});
  LabelService service = Service(/*editable=*/false);
  const nlohmann::json status = service.Status();
  EXPECT_FALSE(status.at("editable").get<bool>());
  EXPECT_EQ(status.at("read_only_reason"), "started with --read-only");
  EXPECT_EQ(service.Labels().at("labels").size(), 1u);
  const int64_t lamp =
      store::Model::Open(path_, store::ModelOptions::ReadOnly()).FindLabel("lamp")->id.value();
  EXPECT_EQ(
      RefusedWith([&] {
        service.AddPoint({{"name", "x"}, {"keyframe", keyframes_[0].value()}, {"pixel", {5, 5}}});
      }),
      403);
  EXPECT_EQ(RefusedWith([&] { service.Edit(lamp, {{"name", "y"}}); }), 403);
  EXPECT_EQ(RefusedWith([&] { service.Remove(lamp); }), 403);
  EXPECT_EQ(store::Model::Open(path_, store::ModelOptions::ReadOnly()).FindLabel("lamp")->name,
            "lamp");
}

}  // namespace
}  // namespace sightmap::cli
