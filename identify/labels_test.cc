#include "identify/labels.h"

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "store/label_files.h"
#include "store/model.h"
#include "store/synthetic_model.h"
#include "tests/test_data.h"

namespace sightmap::identify {
namespace {

// A keyframe looking at the synthetic 2 m wall, posed with a rotation so that world and camera
// coordinates differ on every axis.
struct Fixture {
  store::Model model = store::Model::Open(":memory:");
  KeyframeId keyframe;
  Intrinsics intrinsics;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
};

// `edit_depth` may punch holes in (or set) the keyframe's depth before it is stored.
template <typename EditDepth>
void AddKeyframe(Fixture* f, EditDepth edit_depth) {
  const SessionId session = f->model.BeginSession({});
  store::SyntheticKeyframeOptions options;
  options.width = 320;
  options.height = 240;
  options.num_features = 10;
  store::KeyframeRecord record = store::MakeSyntheticKeyframe(session, 3, options);
  f->world_from_cam = Eigen::Translation3d(0.3, -1.2, 0.8) *
                      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1.0, -0.3).normalized());
  record.world_from_cam = f->world_from_cam;
  record.odom_world_from_cam = f->world_from_cam;
  edit_depth(record.depth);
  f->intrinsics = record.intrinsics;
  f->keyframe = f->model.AddKeyframe(record);
}

void ExpectNear(const Eigen::Vector3d& actual, const Eigen::Vector3d& expected, double tolerance) {
  EXPECT_LT((actual - expected).norm(), tolerance)
      << actual.transpose() << " vs " << expected.transpose();
}

std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

TEST(LabelPointFromPixel, ExactOnAKeyframeWithKnownDepthAndPose) {
  Fixture f;
  AddKeyframe(&f, [](cv::Mat& depth) { depth.at<uint16_t>(80, 100) = 1234; });
  const PixelLabelPoint result =
      LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(100.0, 80.0));
  EXPECT_EQ(result.point.source, store::LabelPointSource::kKeyframePixel);
  EXPECT_EQ(result.point.keyframe, f.keyframe);
  EXPECT_EQ(result.depth_pixel, Eigen::Vector2i(100, 80));
  EXPECT_DOUBLE_EQ(result.depth_offset_px, 0.0);
  EXPECT_DOUBLE_EQ(result.depth_m, 1.234);
  const Eigen::Vector3d cam((100.0 - f.intrinsics.cx) / f.intrinsics.fx * 1.234,
                            (80.0 - f.intrinsics.cy) / f.intrinsics.fy * 1.234, 1.234);
  ExpectNear(result.point.cam_point, cam, 1e-12);
  ExpectNear(result.point.world, f.world_from_cam * cam, 1e-9);

  // Stored, it reads back at the same world point (the store derives it from the pose).
  const store::LabelRecord label = AddPointsToLabel(f.model, "lamp", {result.point});
  ASSERT_EQ(label.points.size(), 1u);
  ExpectNear(label.points[0].world, f.world_from_cam * cam, 1e-9);
  ExpectNear(label.points[0].cam_point, cam, 1e-12);
  EXPECT_EQ(label.points[0].pixel, Eigen::Vector2d(100.0, 80.0));
}

TEST(LabelPointFromPixel, BorrowsTheNearestDepthAlongTheClickedRay) {
  Fixture f;
  AddKeyframe(&f, [](cv::Mat& depth) {
    depth(cv::Rect(196, 146, 9, 9)).setTo(0);  // a hole of radius 4 around (200, 150)
    depth.at<uint16_t>(152, 203) = 1500;       // 3.6 px away
    depth.at<uint16_t>(153, 200) = 1700;       // 3 px away: the nearest
  });
  const PixelLabelPoint result =
      LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(200.0, 150.0));
  EXPECT_EQ(result.depth_pixel, Eigen::Vector2i(200, 153));
  EXPECT_DOUBLE_EQ(result.depth_offset_px, 3.0);
  EXPECT_DOUBLE_EQ(result.depth_m, 1.7);
  ExpectNear(result.point.cam_point, f.intrinsics.Unproject(200.0, 150.0, 1.7), 1e-12);
  // Searching only 2 px finds nothing.
  PixelLabelOptions near;
  near.max_depth_search_px = 2.0;
  EXPECT_THROW(LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(200.0, 150.0), near),
               Error);
}

TEST(LabelPointFromPixel, ClearErrors) {
  Fixture f;
  AddKeyframe(&f, [](cv::Mat& depth) { depth(cv::Rect(100, 100, 41, 41)).setTo(0); });
  try {
    LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(120.0, 120.0));
    FAIL() << "no depth within 5 px must throw";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("no depth within 5 px"), std::string::npos) << message;
    EXPECT_NE(message.find("--point"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  try {
    LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(320.0, 10.0));
    FAIL() << "a pixel outside the image must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("outside keyframe"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(-1.0, 10.0)), Error);
  EXPECT_THROW(LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(NAN, 10.0)), Error);
  try {
    LabelPointFromPixel(f.model, KeyframeId(99), Eigen::Vector2d(10.0, 10.0));
    FAIL() << "an unknown keyframe must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("keyframe 99"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LabelPointFromPixel(f.model, KeyframeId(), Eigen::Vector2d(10.0, 10.0)), Error);
  PixelLabelOptions bad;
  bad.max_depth_search_px = -1.0;
  EXPECT_THROW(LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(10.0, 10.0), bad),
               InvalidArgument);
}

// The keyframe's depth is 2 m at pixel (100, 80) and 0.5 m at (200, 150); a label point 1.5 m out
// along each ray is seen at the first and hidden at the second.
TEST(LabelsInKeyframe, ProjectsPointsAndMarksThoseBehindTheKeyframesSurface) {
  Fixture f;
  AddKeyframe(&f, [](cv::Mat& depth) {
    depth.at<uint16_t>(80, 100) = 2000;
    depth.at<uint16_t>(150, 200) = 500;
  });
  auto world_at = [&](double u, double v, double z) {
    const Eigen::Vector3d cam((u - f.intrinsics.cx) / f.intrinsics.fx * z,
                              (v - f.intrinsics.cy) / f.intrinsics.fy * z, z);
    return Eigen::Vector3d(f.world_from_cam * cam);
  };
  const std::vector<store::LabelRecord> labels = {
      {LabelId(),
       "lamp",
       "lamp",
       {LabelPointFromWorld(world_at(100, 80, 1.5)), LabelPointFromWorld(world_at(200, 150, 1.5)),
        LabelPointFromWorld(f.world_from_cam * Eigen::Vector3d(0, 0, -1.0))}},
      {LabelId(), "far", "appliance", {LabelPointFromWorld(world_at(100, 80, 9.0))}},
  };
  const std::vector<LabelInKeyframe> seen = LabelsInKeyframe(f.model, f.keyframe, labels);
  ASSERT_EQ(seen.size(), 1u) << "the far label is beyond 8 m";
  EXPECT_EQ(seen[0].label, &labels[0]);
  ASSERT_EQ(seen[0].points.size(), 2u) << "the point behind the camera is not drawn";
  EXPECT_EQ(seen[0].points[0].point_index, 0u);
  EXPECT_LT((seen[0].points[0].pixel - Eigen::Vector2d(100, 80)).norm(), 1e-6);
  EXPECT_NEAR(seen[0].points[0].depth_m, 1.5, 1e-9);
  EXPECT_FALSE(seen[0].points[0].hidden);
  EXPECT_EQ(seen[0].points[1].point_index, 1u);
  EXPECT_TRUE(seen[0].points[1].hidden);

  const std::vector<store::KeyframeInfo> keyframes = f.model.Keyframes();
  EXPECT_EQ(KeyframesSeeingLabel(keyframes, labels[0], 5), std::vector<KeyframeId>{f.keyframe});
  EXPECT_TRUE(KeyframesSeeingLabel(keyframes, labels[1], 5).empty());
  EXPECT_TRUE(KeyframesSeeingLabel(keyframes, labels[0], 0).empty());
}

TEST(Labels, APixelLabelFollowsItsKeyframeAfterUpdatePoses) {
  Fixture f;
  AddKeyframe(&f, [](cv::Mat&) {});
  const PixelLabelPoint clicked =
      LabelPointFromPixel(f.model, f.keyframe, Eigen::Vector2d(50.0, 60.0));
  AddPointsToLabel(f.model, "projector", {clicked.point});
  const Eigen::Isometry3d moved =
      Eigen::Translation3d(-2.0, 0.5, 0.1) * Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ());
  f.model.UpdatePoses({{f.keyframe, moved}});
  const std::optional<store::LabelRecord> label = f.model.FindLabel("projector");
  ASSERT_TRUE(label);
  ExpectNear(label->points[0].world, moved * clicked.point.cam_point, 1e-9);
  EXPECT_GT((label->points[0].world - clicked.point.world).norm(), 0.5);
}

TEST(Labels, AddPointsCreatesThenAppendsKeepingTheType) {
  store::Model model = store::Model::Open(":memory:");
  store::LabelRecord lamp = AddPointsToLabel(model, "lamp", {LabelPointFromWorld({1, 2, 3})});
  EXPECT_EQ(lamp.type, kDefaultLabelType);
  lamp = AddPointsToLabel(model, "lamp", {LabelPointFromWorld({4, 5, 6})}, "lamp");
  EXPECT_EQ(lamp.type, "lamp");
  lamp = AddPointsToLabel(model, "lamp", {LabelPointFromWorld({7, 8, 9})});
  EXPECT_EQ(lamp.type, "lamp");
  ASSERT_EQ(lamp.points.size(), 3u);
  ExpectNear(lamp.points[2].world, {7, 8, 9}, 1e-12);
  EXPECT_EQ(lamp.points[2].source, store::LabelPointSource::kTyped);
  EXPECT_THROW(AddPointsToLabel(model, "", {LabelPointFromWorld({1, 2, 3})}), Error);
  EXPECT_THROW(AddPointsToLabel(model, "tv", {}), Error);
  EXPECT_THROW(LabelPointFromWorld({1, NAN, 3}), Error);
  EXPECT_EQ(model.Labels().size(), 1u);
}

TEST(Labels, SceneFileImport) {
  const std::string dir = testing::MakeTempDir("labels_scene");
  const std::string path = WriteFile(dir + "/appliances.json", R"({"scene": "office",
    "appliances": [
      {"id": 1, "name": "monitor_1", "type": "monitor", "points": [[1.5, 2, 0.75]]},
      {"id": 2, "name": "lamp_1", "type": "lamp", "points": [[0, 1, 1.2], [0, 1.1, 1.3]]}]})");
  store::Model model = store::Model::Open(":memory:");
  AddPointsToLabel(model, "lamp_1", {LabelPointFromWorld({9, 9, 9})}, "old");
  AddPointsToLabel(model, "kept", {LabelPointFromWorld({5, 5, 5})});
  const LabelImportReport report = ImportSceneLabels(model, path);
  EXPECT_EQ(report.created, std::vector<std::string>{"monitor_1"});
  EXPECT_EQ(report.replaced, std::vector<std::string>{"lamp_1"});
  EXPECT_EQ(report.points, 3);
  const std::vector<store::LabelRecord> labels = model.Labels();
  ASSERT_EQ(labels.size(), 3u);
  EXPECT_EQ(labels[0].name, "kept");
  EXPECT_EQ(labels[1].name, "lamp_1");
  EXPECT_EQ(labels[1].type, "lamp");
  ASSERT_EQ(labels[1].points.size(), 2u);
  ExpectNear(labels[1].points[1].world, {0, 1.1, 1.3}, 1e-12);
  EXPECT_EQ(labels[1].points[1].source, store::LabelPointSource::kImportedFile);
  EXPECT_EQ(labels[1].points[1].file, path);
  EXPECT_EQ(labels[2].name, "monitor_1");
  EXPECT_EQ(labels[2].type, "monitor");
}

// A 320x240 keyframe at `world_from_cam` whose depth is `depth_mm` everywhere (0: none, as on a
// screen or a window).
KeyframeId AddKeyframeAt(store::Model& model, int index, const Eigen::Isometry3d& world_from_cam,
                         uint16_t depth_mm) {
  store::SyntheticKeyframeOptions options;
  options.width = 320;
  options.height = 240;
  options.num_features = 10;
  store::KeyframeRecord record =
      store::MakeSyntheticKeyframe(model.BeginSession({}), index, options);
  record.world_from_cam = world_from_cam;
  record.odom_world_from_cam = world_from_cam;
  record.depth.setTo(depth_mm);
  return model.AddKeyframe(record);
}

// A camera at `position` looking along world +y (`forward` false: along -y), image y down (-z).
Eigen::Isometry3d LookingAlongY(const Eigen::Vector3d& position, bool forward) {
  const double s = forward ? 1.0 : -1.0;
  Eigen::Matrix3d rotation;
  rotation.col(0) = Eigen::Vector3d(s, 0, 0);
  rotation.col(1) = Eigen::Vector3d(0, 0, -1);
  rotation.col(2) = Eigen::Vector3d(0, s, 0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation;
  pose.translation() = position;
  return pose;
}

// A scene's point may be its appliance's centre (a printer's lies 0.24 m behind its front): the
// user's click lands on the surface that keyframe shows nearest the point.
TEST(ClickedLabelPoint, APointInsideItsApplianceLandsOnTheNearestSurfaceShown) {
  store::Model model = store::Model::Open(":memory:");
  const Eigen::Vector3d centre(0.0, 0.0, 1.0);
  AddKeyframeAt(model, 1, LookingAlongY({0.0, -2.0, 1.0}, true), 1750);  // surface 0.25 m before
  const KeyframeId nearer_surface =
      AddKeyframeAt(model, 2, LookingAlongY({0.3, -2.5, 1.0}, true), 2380);  // 0.12 m before
  AddKeyframeAt(model, 3, LookingAlongY({0.0, -1.0, 1.0}, true), 400);       // 0.6 m before: not it
  const std::optional<PixelLabelPoint> clicked =
      ClickedLabelPoint(model, model.Keyframes(), centre);
  ASSERT_TRUE(clicked);
  EXPECT_EQ(clicked->point.source, store::LabelPointSource::kKeyframePixel);
  EXPECT_EQ(clicked->point.keyframe, nearer_surface);
  EXPECT_DOUBLE_EQ(clicked->depth_m, 2.38);
  EXPECT_NEAR(clicked->point.world.y(), -0.12, 1e-9);
  EXPECT_NEAR(clicked->point.world.z(), 1.0, 1e-9);

  // Stored, it follows its keyframe like a clicked point.
  const store::LabelRecord label = AddPointsToLabel(model, "printer", {clicked->point});
  EXPECT_EQ(label.points[0].keyframe, nearer_surface);
  ExpectNear(label.points[0].world, clicked->point.world, 1e-9);
}

// A switch seen from the room, where the sensor had no depth (or its plate), must not be clicked
// on the far face of its wall from a keyframe in the next room.
TEST(ClickedLabelPoint, NeverFromBehindTheWallTheWalkSawThePointThrough) {
  const Eigen::Vector3d point(0.0, 0.0, 1.0);
  store::Model model = store::Model::Open(":memory:");
  AddKeyframeAt(model, 1, LookingAlongY({0.0, -2.0, 1.0}, true), 0);     // the front: no depth
  AddKeyframeAt(model, 2, LookingAlongY({0.0, 1.5, 1.0}, false), 1300);  // the wall 0.2 m before
  EXPECT_FALSE(ClickedLabelPoint(model, model.Keyframes(), point));

  // Seen from behind only, the click lands on the wall's far face: the walk must show the
  // appliance (labels.h).
  store::Model behind_only = store::Model::Open(":memory:");
  const KeyframeId behind =
      AddKeyframeAt(behind_only, 1, LookingAlongY({0.0, 1.5, 1.0}, false), 1300);
  const std::optional<PixelLabelPoint> clicked =
      ClickedLabelPoint(behind_only, behind_only.Keyframes(), point);
  ASSERT_TRUE(clicked);
  EXPECT_EQ(clicked->point.keyframe, behind);
  EXPECT_NEAR(clicked->point.world.y(), 0.2, 1e-9);
}

TEST(ClickedLabelPoint, NotAtTheImageBorderNorWhereNoKeyframeLooks) {
  store::Model model = store::Model::Open(":memory:");
  const Eigen::Isometry3d pose = LookingAlongY({0.0, -2.0, 1.0}, true);
  AddKeyframeAt(model, 1, pose, 2000);
  const Intrinsics k = model.Keyframes().front().intrinsics;
  auto world_at = [&](double u, double v) {
    return Eigen::Vector3d(pose *
                           Eigen::Vector3d((u - k.cx) / k.fx * 2.0, (v - k.cy) / k.fy * 2.0, 2.0));
  };
  EXPECT_TRUE(ClickedLabelPoint(model, model.Keyframes(), world_at(0.5 * k.width, 0.5 * k.height)));
  EXPECT_FALSE(
      ClickedLabelPoint(model, model.Keyframes(), world_at(0.05 * k.width, 0.5 * k.height)))
      << "within 10% of the border";
  EXPECT_FALSE(ClickedLabelPoint(model, model.Keyframes(), Eigen::Vector3d(0.0, -5.0, 1.0)))
      << "behind the camera";
  ClickOptions bad;
  bad.border_share = 0.5;
  EXPECT_THROW(ClickedLabelPoint(model, model.Keyframes(), world_at(100, 100), bad),
               InvalidArgument);
}

TEST(Labels, SceneFileImportAsClickedReportsThePointsNoKeyframeShows) {
  const std::string dir = testing::MakeTempDir("labels_scene_clicked");
  const std::string path = WriteFile(dir + "/appliances.json", R"({"scene": "office",
    "appliances": [
      {"id": 1, "name": "printer", "type": "printer", "points": [[0, 0, 1]]},
      {"id": 2, "name": "unseen", "type": "lamp", "points": [[0, 9, 1]]}]})");
  store::Model model = store::Model::Open(":memory:");
  const KeyframeId keyframe = AddKeyframeAt(model, 1, LookingAlongY({0.0, -2.0, 1.0}, true), 1750);
  const LabelImportReport report = ImportSceneLabels(model, path, ClickOptions());
  EXPECT_EQ(report.points, 2);
  EXPECT_EQ(report.clicked_points, 1);
  EXPECT_EQ(report.not_clicked, std::vector<std::string>{"unseen"});
  const std::vector<store::LabelRecord> labels = model.Labels();
  ASSERT_EQ(labels.size(), 2u);
  EXPECT_EQ(labels[0].name, "printer");
  EXPECT_EQ(labels[0].points[0].source, store::LabelPointSource::kKeyframePixel);
  EXPECT_EQ(labels[0].points[0].keyframe, keyframe);
  ExpectNear(labels[0].points[0].world, {0.0, -0.25, 1.0}, 1e-9);
  EXPECT_EQ(labels[1].points[0].source, store::LabelPointSource::kImportedFile);
  ExpectNear(labels[1].points[0].world, {0, 9, 1}, 1e-12);

  // Without it, the file's points as given.
  const LabelImportReport plain = ImportSceneLabels(model, path);
  EXPECT_EQ(plain.clicked_points, 0);
  EXPECT_TRUE(plain.not_clicked.empty());
  ExpectNear(model.Labels()[0].points[0].world, {0, 0, 1}, 1e-12);
}

TEST(Labels, ABadSceneFileLeavesTheModelUnchanged) {
  const std::string dir = testing::MakeTempDir("labels_bad_scene");
  store::Model model = store::Model::Open(":memory:");
  AddPointsToLabel(model, "lamp_1", {LabelPointFromWorld({9, 9, 9})}, "old");
  const auto expect_refused = [&](const std::string& name, const std::string& text,
                                  const std::string& fragment) {
    const std::string path = WriteFile(dir + "/" + name, text);
    try {
      ImportSceneLabels(model, path);
      ADD_FAILURE() << name << " was accepted";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(fragment), std::string::npos) << name << ": " << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
    const std::vector<store::LabelRecord> labels = model.Labels();
    ASSERT_EQ(labels.size(), 1u) << name;
    EXPECT_EQ(labels[0].type, "old");
    ExpectNear(labels[0].points.at(0).world, {9, 9, 9}, 1e-12);
  };
  // The first appliance is good each time, so nothing may be written before validation ends.
  const std::string good = R"({"name": "lamp_1", "type": "lamp", "points": [[0, 1, 1]]})";
  expect_refused("truncated.json", R"({"appliances": [)" + good, "not valid JSON");
  expect_refused("no_list.json", R"({"scene": "office"})", "no \"appliances\"");
  expect_refused("empty.json", R"({"appliances": []})", "no appliance");
  expect_refused("no_name.json", R"({"appliances": [)" + good + R"(, {"points": [[1, 2, 3]]}]})",
                 "appliance 2 has no \"name\"");
  expect_refused("no_points.json", R"({"appliances": [)" + good + R"(, {"name": "tv"}]})",
                 "has no \"points\"");
  expect_refused("two_coordinates.json",
                 R"({"appliances": [)" + good + R"(, {"name": "tv", "points": [[1, 2]]}]})",
                 "point 1 is not [x, y, z]");
  expect_refused("string_coordinate.json",
                 R"({"appliances": [)" + good + R"(, {"name": "tv", "points": [[1, "2", 3]]}]})",
                 "three finite numbers");
  expect_refused("twice.json", R"({"appliances": [)" + good + ", " + good + "]}",
                 "both appliance 1 and appliance 2");
  EXPECT_THROW(ImportSceneLabels(model, dir + "/missing.json"), Error);
}

TEST(Labels, PointListFilesImportAllOrNothing) {
  const std::string dir = testing::MakeTempDir("labels_point_lists");
  const std::string tv = WriteFile(dir + "/tv.txt", "// CloudCompare\n1 2 3\n1.5,2.5,3.5\n");
  const std::string lamp = WriteFile(dir + "/lamp.asc", "0 0 1\n");
  const std::string empty = WriteFile(dir + "/empty.txt", "no points here\n");
  store::Model model = store::Model::Open(":memory:");
  AddPointsToLabel(model, "lamp", {LabelPointFromWorld({9, 9, 9})}, "lamp");

  EXPECT_THROW(ImportPointListLabels(model, {tv, empty}), Error);
  EXPECT_THROW(ImportPointListLabels(model, {tv, dir + "/missing.txt"}), Error);
  EXPECT_THROW(ImportPointListLabels(model, {tv, WriteFile(dir + "/tv.csv", "1 1 1\n")}), Error);
  EXPECT_THROW(ImportPointListLabels(model, {}), Error);
  ASSERT_EQ(model.Labels().size(), 1u);

  const LabelImportReport report = ImportPointListLabels(model, {tv, lamp});
  EXPECT_EQ(report.created, std::vector<std::string>{"tv"});
  EXPECT_EQ(report.replaced, std::vector<std::string>{"lamp"});
  EXPECT_EQ(report.points, 3);
  const std::optional<store::LabelRecord> tv_label = model.FindLabel("tv");
  ASSERT_TRUE(tv_label);
  EXPECT_EQ(tv_label->type, kDefaultLabelType);
  ASSERT_EQ(tv_label->points.size(), 2u);
  ExpectNear(tv_label->points[1].world, {1.5, 2.5, 3.5}, 1e-12);
  EXPECT_EQ(tv_label->points[1].source, store::LabelPointSource::kImportedFile);
  EXPECT_EQ(tv_label->points[1].file, tv);
  const std::optional<store::LabelRecord> lamp_label = model.FindLabel("lamp");
  ASSERT_TRUE(lamp_label);
  EXPECT_EQ(lamp_label->type, "lamp");  // kept: no type given
  ASSERT_EQ(lamp_label->points.size(), 1u);
  ExpectNear(lamp_label->points[0].world, {0, 0, 1}, 1e-12);

  ImportPointListLabels(model, {lamp}, std::string("ceiling_light"));
  EXPECT_EQ(model.FindLabel("lamp")->type, "ceiling_light");
}

}  // namespace
}  // namespace sightmap::identify
