#include "synthesis/view_synthesis.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "identify/locator.h"
#include "identify/sim_model_testing.h"

namespace sightmap::synthesis {
namespace {

namespace fs = std::filesystem;

Intrinsics SmallCamera() {
  Intrinsics k;
  k.width = 64;
  k.height = 48;
  k.fx = k.fy = 60.0;
  k.cx = 31.5;
  k.cy = 23.5;
  return k;
}

TEST(PlanStandpoints, OneViewPerOpenDistanceOfEachMissingSectorAtEyeHeight) {
  identify::ModelCoverage coverage;
  coverage.eye_height_m = 1.4;
  identify::LabelCoverage label;
  label.id = LabelId(3);
  label.name = "thermostat";
  label.centre = Eigen::Vector3d(2.0, 1.0, 1.5);
  label.sectors.resize(4);
  for (int s = 0; s < 4; ++s) {
    label.sectors[s].from_deg = 90.0 * s;
    label.sectors[s].to_deg = 90.0 * (s + 1);
  }
  label.sectors[0].open_distances_m = {1.5, 2.5};  // open, not seen: two views
  label.sectors[1].open_distances_m = {1.5};       // open and seen: none by default
  label.sectors[1].keyframes = 2;
  label.sectors[2].keyframes = 1;  // seen from a distance nobody could stand at now: none
  // sector 3 closed (behind the wall): none
  coverage.labels.push_back(label);

  ViewSynthesisOptions options;
  std::vector<Standpoint> standpoints = PlanStandpoints(coverage, options);
  ASSERT_EQ(standpoints.size(), 2u);
  for (const Standpoint& standpoint : standpoints) {
    EXPECT_EQ(standpoint.label, LabelId(3));
    EXPECT_EQ(standpoint.label_name, "thermostat");
    EXPECT_DOUBLE_EQ(standpoint.bearing_deg, 45.0);
    const Eigen::Vector3d eye = standpoint.world_from_cam.translation();
    EXPECT_NEAR(eye.z(), 1.4, 1e-12);
    const Eigen::Vector2d offset = (eye - label.centre).head<2>();
    EXPECT_NEAR(offset.norm(), standpoint.distance_m, 1e-9);
    EXPECT_NEAR(RadToDeg(std::atan2(offset.y(), offset.x())), 45.0, 1e-9);
    const Eigen::Vector3d in_cam = standpoint.world_from_cam.inverse() * label.centre;
    EXPECT_NEAR(in_cam.head<2>().norm(), 0.0, 1e-9);  // the label at the image centre
  }
  EXPECT_DOUBLE_EQ(standpoints[0].distance_m, 1.5);
  EXPECT_DOUBLE_EQ(standpoints[1].distance_m, 2.5);

  options.missing_sectors_only = false;
  EXPECT_EQ(PlanStandpoints(coverage, options).size(), 3u);

  // A ceiling light straight above the nearest standpoint is too steep to photograph.
  coverage.labels[0].centre.z() = 1.4 + 1.5 * std::tan(DegToRad(70.0));
  options.missing_sectors_only = true;
  standpoints = PlanStandpoints(coverage, options);
  ASSERT_EQ(standpoints.size(), 1u);
  EXPECT_DOUBLE_EQ(standpoints[0].distance_m, 2.5);
}

// A room 8 m square of free floor, a wall across it at x = 4.0-4.2 m, a desk by (3, 6), a label
// on the west side, and one keyframe that saw it from the south.
TEST(PlanGridStandpoints, FreeFloorInPlainSightOfALabelTheWalkDidNotSeeFromThere) {
  identify::ModelCoverage coverage;
  coverage.eye_height_m = 1.4;
  identify::FloorPlan& plan = coverage.floor;
  plan.cell_m = 0.2;
  plan.cells = cv::Mat(40, 40, CV_8UC1, cv::Scalar(identify::FloorPlan::kFree));
  plan.cells.col(20).setTo(identify::FloorPlan::kSurface);
  // A desk corner 0.28 m from the grid point (3, 6), off its line of sight to the label.
  plan.cells.at<uint8_t>(31, 16) = identify::FloorPlan::kSurface;
  identify::LabelCoverage label;
  label.id = LabelId(5);
  label.name = "switch";
  label.centre = Eigen::Vector3d(1.0, 4.0, 1.5);
  coverage.labels.push_back(label);
  store::KeyframeInfo keyframe;
  keyframe.intrinsics = SmallCamera();
  keyframe.world_from_cam =
      LookAt(Eigen::Vector3d(1.0, 1.5, 1.4), label.centre, Eigen::Vector3d::UnitZ());

  ViewSynthesisOptions options;
  EXPECT_TRUE(PlanGridStandpoints(coverage, {keyframe}, options).empty());  // off by default
  options.grid_step_m = 1.0;
  const std::vector<Standpoint> standpoints = PlanGridStandpoints(coverage, {keyframe}, options);
  ASSERT_FALSE(standpoints.empty());
  std::vector<Eigen::Vector2d> at;
  for (const Standpoint& standpoint : standpoints) {
    EXPECT_EQ(standpoint.label, LabelId(5));
    EXPECT_EQ(standpoint.label_name, "switch");
    const Eigen::Vector3d eye = standpoint.world_from_cam.translation();
    EXPECT_NEAR(eye.z(), 1.4, 1e-12);
    EXPECT_NEAR(eye.x(), std::round(eye.x()), 1e-9);  // on the 1 m grid
    EXPECT_NEAR(eye.y(), std::round(eye.y()), 1e-9);
    EXPECT_LT(eye.x(), 4.0);  // the wall hides the label beyond it
    const double distance = (eye - label.centre).head<2>().norm();
    EXPECT_NEAR(standpoint.distance_m, distance, 1e-9);
    EXPECT_GE(distance, options.coverage.min_distance_m);
    EXPECT_LE(distance, options.coverage.max_distance_m);
    const Eigen::Vector3d in_cam = standpoint.world_from_cam.inverse() * label.centre;
    EXPECT_NEAR(in_cam.head<2>().norm(), 0.0, 1e-9);  // looking at the label
    at.push_back(eye.head<2>());
  }
  const auto planned = [&at](double x, double y) {
    return std::any_of(at.begin(), at.end(), [&](const Eigen::Vector2d& p) {
      return (p - Eigen::Vector2d(x, y)).norm() < 1e-9;
    });
  };
  EXPECT_TRUE(planned(3.0, 4.0));   // from the east: 90 deg from the keyframe's view
  EXPECT_TRUE(planned(1.0, 7.0));   // from the north, 3 m
  EXPECT_TRUE(planned(3.0, 3.0));   // 63 deg from the keyframe's view
  EXPECT_FALSE(planned(1.0, 2.0));  // the keyframe's own view
  EXPECT_FALSE(planned(2.0, 2.0));  // 27 deg from it, at a similar distance
  EXPECT_FALSE(planned(3.0, 6.0));  // nobody fits beside the desk
  EXPECT_FALSE(planned(5.0, 4.0));  // behind the wall
  EXPECT_FALSE(planned(1.0, 4.0));  // at the label

  // Without the keyframe, its view is planned too.
  const std::vector<Standpoint> unseen = PlanGridStandpoints(coverage, {}, options);
  EXPECT_GT(unseen.size(), standpoints.size());
}

TEST(KeyframeMesh, TrianglesFollowTheDepthAndStopAtItsEdges) {
  const Intrinsics k = SmallCamera();
  // Left half a wall at 2 m, right half one at 3 m (a depth edge), top rows without depth.
  cv::Mat depth(k.height, k.width, CV_16UC1, cv::Scalar(2000));
  depth(cv::Rect(32, 0, 32, 48)).setTo(3000);
  depth(cv::Rect(0, 0, 64, 8)).setTo(0);
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.translation() = Eigen::Vector3d(1, 2, 3);
  ViewSynthesisOptions options;
  options.mesh_step_px = 4;
  const render::TriangleMesh mesh = KeyframeMesh(depth, k, world_from_cam, 5, options);
  EXPECT_EQ(mesh.material.texture, 5);
  EXPECT_TRUE(mesh.material.unlit);
  ASSERT_FALSE(mesh.positions.empty());
  ASSERT_EQ(mesh.positions.size() % 3, 0u);
  ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
  // Grid columns 0..15 (u = 0..60), rows 2..11 with depth: quads within a half, not across.
  // Left quads: columns 0-7 (u 0..28 to 4..32: the one at u = 28 reaches u = 32, the 3 m side).
  const size_t quads = mesh.positions.size() / 6;
  EXPECT_EQ(quads, static_cast<size_t>((7 + 7) * 9));
  for (size_t t = 0; t < mesh.positions.size(); t += 3) {
    const float z0 = mesh.positions[t].z() - 3.0f;
    for (size_t i = t; i < t + 3; ++i) {
      EXPECT_NEAR(mesh.positions[i].z() - 3.0f, z0, 1e-5);  // one wall per triangle
      EXPECT_TRUE(z0 > 1.99f && z0 < 3.01f);
      EXPECT_TRUE(mesh.uvs[i].x() > 0.0f && mesh.uvs[i].x() < 1.0f);
      EXPECT_TRUE(mesh.uvs[i].y() > 0.0f && mesh.uvs[i].y() < 1.0f);
    }
  }
  // A vertex lies where its pixel's ray meets its depth, in the world.
  const Eigen::Vector3f expected = (world_from_cam * k.Unproject(0, 8, 2.0)).cast<float>();
  EXPECT_TRUE(std::any_of(mesh.positions.begin(), mesh.positions.end(),
                          [&](const Eigen::Vector3f& p) { return (p - expected).norm() < 1e-5f; }));
  EXPECT_THROW(KeyframeMesh(depth(cv::Rect(0, 0, 32, 48)), k, world_from_cam, 0, options), Error);
}

TEST(CompositeLayers, NearestSurfaceWinsAndTheBestSourceColoursIt) {
  const cv::Size size(4, 1);
  render::RenderedView best;
  best.color = cv::Mat(size, CV_8UC3, cv::Scalar(10, 10, 10));
  best.depth = (cv::Mat_<float>(1, 4) << 2.0f, 2.0f, 0.0f, 0.0f);
  render::RenderedView other;
  other.color = cv::Mat(size, CV_8UC3, cv::Scalar(200, 200, 200));
  // Pixel 0: the other source sees the same wall 1% nearer (best colours it); pixel 1: a surface
  // much nearer (the other's); pixel 2: only the other; pixel 3: nothing.
  other.depth = (cv::Mat_<float>(1, 4) << 1.98f, 1.0f, 4.0f, 0.0f);
  const Composite composite = CompositeLayers({best, other}, 0.03);
  EXPECT_EQ(composite.drawn_pixels, 3);
  EXPECT_EQ(composite.color.at<cv::Vec3b>(0, 0)[0], 10);
  EXPECT_FLOAT_EQ(composite.depth_m.at<float>(0, 0), 2.0f);
  EXPECT_EQ(composite.color.at<cv::Vec3b>(0, 1)[0], 200);
  EXPECT_FLOAT_EQ(composite.depth_m.at<float>(0, 1), 1.0f);
  EXPECT_EQ(composite.color.at<cv::Vec3b>(0, 2)[0], 200);
  EXPECT_FLOAT_EQ(composite.depth_m.at<float>(0, 3), 0.0f);
  EXPECT_EQ(composite.color.at<cv::Vec3b>(0, 3)[0], 0);
  render::RenderedView wrong_size = other;
  wrong_size.depth = cv::Mat::zeros(2, 4, CV_32F);
  EXPECT_THROW(CompositeLayers({best, wrong_size}, 0.03), Error);
  EXPECT_THROW(CompositeLayers({}, 0.03), Error);
}

TEST(KeepFeaturesOnDrawnPixels, DropsCornersWhosePatchTouchesAHole) {
  cv::Mat drawn(100, 100, CV_8U, cv::Scalar(255));
  drawn(cv::Rect(60, 0, 40, 100)).setTo(0);  // a hole on the right
  Features features;
  features.keypoints = {cv::KeyPoint(20, 50, 31), cv::KeyPoint(50, 50, 31),
                        cv::KeyPoint(40, 50, 31), cv::KeyPoint(80, 50, 31)};
  features.descriptors = (cv::Mat_<uint8_t>(4, 1) << 1, 2, 3, 4);
  features.points_cam = {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 0, 0),
                         Eigen::Vector3d(3, 0, 0), Eigen::Vector3d(4, 0, 0)};
  features.has_point = {true, true, false, true};
  const Features kept = KeepFeaturesOnDrawnPixels(features, drawn);
  // 20: 40 px from the hole; 50: 10 px (its 31 px patch reaches it); 40: 20 px; 80: in it.
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_FLOAT_EQ(kept.keypoints[0].pt.x, 20.0f);
  EXPECT_FLOAT_EQ(kept.keypoints[1].pt.x, 40.0f);
  EXPECT_EQ(kept.descriptors.at<uint8_t>(0, 0), 1);
  EXPECT_EQ(kept.descriptors.at<uint8_t>(1, 0), 3);
  EXPECT_EQ(kept.has_point, (std::vector<bool>{true, false}));
  EXPECT_TRUE(kept.IsConsistent());
}

TEST(ViewSynthesisOptions, AreChecked) {
  ViewSynthesisOptions options;
  EXPECT_TRUE(options.Check(nullptr));
  std::string why;
  options.mesh_step_px = 0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("mesh_step_px"), std::string::npos);
  options = ViewSynthesisOptions();
  options.max_depth_m = 0.2;
  EXPECT_FALSE(options.Check(&why));
  options = ViewSynthesisOptions();
  options.min_drawn_share = 1.5;
  EXPECT_FALSE(options.Check(&why));
  options = ViewSynthesisOptions();
  options.grid_step_m = -1.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("grid_step_m"), std::string::npos);
  options.grid_step_m = 0.05;  // a view every 5 cm: thousands of near-copies
  EXPECT_FALSE(options.Check(&why));
  options = ViewSynthesisOptions();
  options.grid_seen.max_angle_deg = 0.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("grid_seen"), std::string::npos);
}

// The office walk with ground-truth poses, every appliance labelled: one model for the suite.
class SynthesisOnTheWalk : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("sightmap-synthesis-test-" + std::to_string(::getpid())));
    fs::create_directories(*dir_);
    identify::SimModelOptions options;
    options.keyframes = 60;
    identify::BuildSimulatorModel((*dir_ / "model.db").string(), options);
  }
  static void TearDownTestSuite() {
    std::error_code ignored;
    fs::remove_all(*dir_, ignored);
    delete dir_;
  }
  static std::string ModelPath() { return (*dir_ / "model.db").string(); }
  static fs::path* dir_;
};
fs::path* SynthesisOnTheWalk::dir_ = nullptr;

// A keyframe's own view rendered from the other keyframes looks like the keyframe: its colour
// and depth agree where drawn, and most of it is drawn.
TEST_F(SynthesisOnTheWalk, AKeyframesViewFromTheOthersLooksLikeIt) {
  const store::Model model = store::Model::Open(ModelPath(), store::ModelOptions::ReadOnly());
  ViewSynthesisOptions options;
  const ViewSynthesizer synthesizer(model, options);
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  int compared = 0;
  int tried = 0;
  for (size_t index = 10; index < keyframes.size(); index += 5) {
    const store::KeyframeInfo& info = keyframes[index];
    const cv::Mat depth = model.LoadDepth(info.id);
    // The target: the point at the image centre.
    const double z =
        depth.at<uint16_t>(info.intrinsics.height / 2, info.intrinsics.width / 2) / 1e3;
    if (z < 0.5) continue;
    ++tried;
    const Eigen::Vector3d target =
        info.world_from_cam *
        info.intrinsics.Unproject(info.intrinsics.width / 2, info.intrinsics.height / 2, z);
    const std::vector<KeyframeId> sources =
        synthesizer.ChooseSources(info.world_from_cam, target, info.id);
    EXPECT_TRUE(std::find(sources.begin(), sources.end(), info.id) == sources.end());
    const ViewSynthesizer::Result result =
        synthesizer.Synthesize(info.world_from_cam, target, info.id);
    // Some views are refused (the other keyframes saw too little of it, or too few corners):
    // what is drawn must be right, and a third of the views at least drawn (4 of 8 here).
    if (!result.view) continue;
    ++compared;
    EXPECT_GT(result.drawn_share, 0.5) << index;
    EXPECT_GE(result.features, options.min_features);
    EXPECT_TRUE(result.view->world_from_cam.isApprox(info.world_from_cam, 1e-9));
    EXPECT_TRUE(result.view->features.IsConsistent());
    // Colour: the median absolute grey difference over drawn pixels is small.
    cv::Mat rendered_grey;
    cv::Mat real_grey;
    cv::cvtColor(result.view->color, rendered_grey, cv::COLOR_BGR2GRAY);
    cv::cvtColor(model.LoadColor(info.id), real_grey, cv::COLOR_BGR2GRAY);
    std::vector<int> differences;
    for (int v = 0; v < real_grey.rows; v += 2) {
      for (int u = 0; u < real_grey.cols; u += 2) {
        if (result.view->color.at<cv::Vec3b>(v, u) == cv::Vec3b(0, 0, 0)) continue;
        differences.push_back(
            std::abs(rendered_grey.at<uint8_t>(v, u) - real_grey.at<uint8_t>(v, u)));
      }
    }
    ASSERT_FALSE(differences.empty());
    std::nth_element(differences.begin(), differences.begin() + differences.size() / 2,
                     differences.end());
    EXPECT_LT(differences[differences.size() / 2], 20) << index;
    // The features' 3D points agree with the keyframe's depth at their pixels.
    int agreeing = 0;
    int checked = 0;
    for (size_t i = 0; i < result.view->features.size(); ++i) {
      if (!result.view->features.has_point[i]) continue;
      const cv::Point2f p = result.view->features.keypoints[i].pt;
      const double real = depth.at<uint16_t>(cvRound(p.y), cvRound(p.x)) / 1e3;
      if (real <= 0.0) continue;
      ++checked;
      agreeing += std::abs(result.view->features.points_cam[i].z() - real) < 0.05 + 0.02 * real;
    }
    ASSERT_GT(checked, 0);
    EXPECT_GT(static_cast<double>(agreeing) / checked, 0.8) << index;
  }
  EXPECT_GE(tried, 5);
  EXPECT_GE(3 * compared, tried) << compared << " of " << tried << " views rendered";
}

TEST_F(SynthesisOnTheWalk, ViewsAroundLabelsAreStoredReplacedAndLocatedAgainst) {
  const std::string path = (*dir_ / "views.db").string();
  fs::copy_file(ModelPath(), path, fs::copy_options::overwrite_existing);
  store::Model model = store::Model::Open(path);
  ViewSynthesisOptions options;
  options.missing_sectors_only = false;  // 60 s of walk: few sectors are both open and unseen
  int reported = 0;
  const SynthesisReport first =
      SynthesizeViews(model, options, [&](int done, int total) { reported = done == total; });
  EXPECT_EQ(reported, 1);
  EXPECT_GT(first.standpoints, 0);
  EXPECT_GT(first.written, 0);
  EXPECT_EQ(first.written + first.refused, first.standpoints);
  EXPECT_EQ(first.deleted, 0);  // nothing to replace: its own views stay
  EXPECT_EQ(static_cast<int>(first.refusals.size()), first.refused);
  EXPECT_EQ(model.NumSyntheticViews(), first.written);
  EXPECT_EQ(model.Summary().synthetic_view_bytes, first.bytes);
  const std::vector<store::LabelRecord> labels = model.Labels();
  for (const store::SyntheticViewRecord& view : model.SyntheticViews()) {
    EXPECT_TRUE(view.label.valid());
    EXPECT_GE(static_cast<int>(view.features.NumPoints()), options.min_features);
    // It looks at its label from where a person stands.
    const auto label = std::find_if(labels.begin(), labels.end(), [&](const store::LabelRecord& l) {
      return l.id == view.label;
    });
    ASSERT_NE(label, labels.end());
    const Eigen::Vector3d in_cam = view.world_from_cam.inverse() * label->points.front().world;
    EXPECT_GT(in_cam.z(), 0.9);
    EXPECT_LT(in_cam.z(), 4.1);
  }

  // The Locator loads them beside the keyframes, or not, as asked.
  const identify::Locator with(model);
  EXPECT_EQ(with.NumKeyframes(), 60u);
  EXPECT_EQ(with.NumSyntheticViews(), static_cast<size_t>(first.written));
  identify::LocatorOptions without_options;
  without_options.use_synthetic_views = false;
  const identify::Locator without(model, without_options);
  EXPECT_EQ(without.NumSyntheticViews(), 0u);

  // A second run replaces the views rather than adding to them, and keeps the old ones until the
  // new ones are written (a run killed half-way loses nothing).
  int64_t fewest_during = INT64_MAX;
  const SynthesisReport second = SynthesizeViews(model, options, [&](int, int) {
    fewest_during = std::min(fewest_during, model.NumSyntheticViews());
  });
  EXPECT_GE(fewest_during, first.written);
  EXPECT_EQ(second.deleted, first.written);
  EXPECT_EQ(model.NumSyntheticViews(), second.written);

  // A model without labels has nothing to render views around.
  for (const store::LabelRecord& label : labels) model.DeleteLabel(label.id);
  try {
    SynthesizeViews(model, options);
    ADD_FAILURE() << "a model without labels must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no labels"), std::string::npos) << e.what();
  }
  EXPECT_EQ(model.NumSyntheticViews(), second.written);  // nothing lost on refusal
}

}  // namespace
}  // namespace sightmap::synthesis
