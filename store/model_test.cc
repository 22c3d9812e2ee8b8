#include "store/model.h"

#include <sqlite3.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "store/schema.h"
#include "store/store_test_util.h"
#include "store/synthetic_model.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

namespace sightmap::store {
namespace {

using testing::CountLines;

SyntheticKeyframeOptions SmallKeyframes() {
  SyntheticKeyframeOptions options;
  options.width = 64;
  options.height = 48;
  options.num_features = 50;
  return options;
}

Eigen::Isometry3d MakePose(double angle_rad, const Eigen::Vector3d& t) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() =
      Eigen::AngleAxisd(angle_rad, Eigen::Vector3d(0.3, 1.0, -0.2).normalized()).toRotationMatrix();
  pose.translation() = t;
  return pose;
}

TEST(Model, KeyframeRoundTripWithFeaturesAndLinks) {
  Model model = Model::Open(":memory:");
  EXPECT_EQ(model.SchemaVersion(), Model::LatestSchemaVersion());
  SessionRecord session;
  session.source = "tum:/data/fr1";
  session.device_name = "Xtion";
  session.device_serial = "1234";
  session.intrinsics = SyntheticIntrinsics(64, 48);
  session.options_json = R"({"keyframe_hz":1})";
  const SessionId session_id = model.BeginSession(session);

  KeyframeRecord first = MakeSyntheticKeyframe(session_id, 0, SmallKeyframes());
  first.world_from_cam = MakePose(0.3, {1.0, 2.0, 3.0});
  first.odom_world_from_cam = MakePose(0.25, {1.1, 2.0, 3.0});
  const KeyframeId a = model.AddKeyframe(first);
  // Big enough that the texture is not finer than JPEG's chroma subsampling.
  SyntheticKeyframeOptions medium = SmallKeyframes();
  medium.width = 320;
  medium.height = 240;
  KeyframeRecord second = MakeSyntheticKeyframe(session_id, 1, medium);
  LinkRecord odometry;
  odometry.from = a;  // `to` left invalid: the keyframe being added
  odometry.type = LinkType::kOdometry;
  odometry.to_in_from = MakePose(0.1, {0.1, 0.0, 0.0});
  odometry.information(0, 0) = 400.0;
  odometry.information(3, 5) = odometry.information(5, 3) = 0.5;
  second.links.push_back(odometry);
  const KeyframeId b = model.AddKeyframe(second);
  EXPECT_TRUE(a.valid() && b.valid() && a != b);

  const std::vector<KeyframeInfo> keyframes = model.Keyframes();
  ASSERT_EQ(keyframes.size(), 2u);
  EXPECT_EQ(keyframes[0].id, a);
  EXPECT_EQ(keyframes[0].session, session_id);
  EXPECT_TRUE(keyframes[0].world_from_cam.isApprox(first.world_from_cam, 1e-12));
  EXPECT_TRUE(keyframes[0].odom_world_from_cam.isApprox(first.odom_world_from_cam, 1e-12));
  EXPECT_EQ(keyframes[1].timestamp_ns, 1000000000);
  EXPECT_EQ(keyframes[1].intrinsics.width, 320);
  EXPECT_DOUBLE_EQ(keyframes[1].intrinsics.fx, second.intrinsics.fx);
  EXPECT_EQ(keyframes[1].num_features, 50);
  EXPECT_GT(keyframes[1].color_bytes, 0);

  // Depth is lossless; colour is JPEG, so close but not equal.
  const cv::Mat depth = model.LoadDepth(b);
  EXPECT_EQ(cv::norm(depth, second.depth, cv::NORM_INF), 0.0);
  const cv::Mat color = model.LoadColor(b);
  ASSERT_EQ(color.size(), second.color.size());
  EXPECT_LT(cv::norm(color, second.color, cv::NORM_L1) / color.total() / 3, 6.0);
  // Grey at a quarter of the size, decoded scaled: the colour image's grey, area-averaged.
  const cv::Mat grey = model.LoadGrey(b, 4);
  ASSERT_EQ(grey.type(), CV_8UC1);
  ASSERT_EQ(grey.size(), cv::Size(second.color.cols / 4, second.color.rows / 4));
  cv::Mat expected_grey;
  cv::cvtColor(second.color, expected_grey, cv::COLOR_BGR2GRAY);
  cv::resize(expected_grey, expected_grey, grey.size(), 0, 0, cv::INTER_AREA);
  EXPECT_LT(cv::norm(grey, expected_grey, cv::NORM_L1) / grey.total(), 6.0);
  EXPECT_EQ(model.LoadGrey(b).size(), second.color.size());
  EXPECT_THROW(model.LoadGrey(b, 3), InvalidArgument);

  const Features features = model.LoadFeatures(b);
  ASSERT_EQ(features.keypoints.size(), 50u);
  EXPECT_FLOAT_EQ(features.keypoints[7].pt.x, second.features.keypoints[7].pt.x);
  EXPECT_EQ(features.keypoints[7].octave, second.features.keypoints[7].octave);
  EXPECT_EQ(cv::norm(features.descriptors, second.features.descriptors, cv::NORM_INF), 0.0);
  EXPECT_EQ(features.descriptors.type(), CV_8U);
  // Stored as float32: depth noise is millimetres.
  EXPECT_NEAR((features.points_cam[9] - second.features.points_cam[9]).norm(), 0.0, 1e-6);
  EXPECT_EQ(features.has_point, second.features.has_point);

  const std::vector<LinkRecord> links = model.Links();
  ASSERT_EQ(links.size(), 1u);
  EXPECT_EQ(links[0].from, a);
  EXPECT_EQ(links[0].to, b);
  EXPECT_TRUE(links[0].to_in_from.isApprox(odometry.to_in_from, 1e-12));
  EXPECT_EQ(links[0].information, odometry.information);

  const std::vector<SessionRecord> sessions = model.Sessions();
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_EQ(sessions[0].device_serial, "1234");
  EXPECT_EQ(sessions[0].options_json, session.options_json);
  EXPECT_EQ(sessions[0].end_state, SessionEnd::kRunning);
  EXPECT_EQ(model.IntegrityCheck(), "ok");
}

TEST(Model, FloatDescriptorsAndKeypointsWithoutAPointRoundTrip) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  KeyframeRecord keyframe = MakeSyntheticKeyframe(session, 0, SmallKeyframes());
  keyframe.features.descriptors = cv::Mat(50, 128, CV_32F);
  cv::randu(keyframe.features.descriptors, -1.0, 1.0);
  keyframe.features.has_point[3] = false;
  keyframe.features.points_cam[3] = Eigen::Vector3d(1.0, 2.0, 3.0);  // not a point: not kept
  const KeyframeId id = model.AddKeyframe(keyframe);
  const Features features = model.LoadFeatures(id);
  EXPECT_EQ(features.descriptors.type(), CV_32F);
  EXPECT_EQ(features.descriptors.cols, 128);
  EXPECT_EQ(cv::norm(features.descriptors, keyframe.features.descriptors, cv::NORM_INF), 0.0);
  ASSERT_EQ(features.has_point.size(), 50u);
  EXPECT_FALSE(features.has_point[3]);
  EXPECT_EQ(features.points_cam[3], Eigen::Vector3d::Zero());
  EXPECT_EQ(features.NumPoints(), 49u);
  EXPECT_TRUE(features.IsConsistent());
}

// RootSIFT-like byte rows for photos, written with the keyframe or later (replacing), read back
// as written; a keyframe without them has none, and deleting nothing else is needed.
TEST(Model, PhotoFeaturesRoundTripWithTheKeyframeOrAddedLater) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  KeyframeRecord keyframe = MakeSyntheticKeyframe(session, 0, SmallKeyframes());
  keyframe.photo_features = keyframe.features;
  keyframe.photo_features->descriptors = cv::Mat(50, 128, CV_8U);
  cv::randu(keyframe.photo_features->descriptors, 0, 256);
  keyframe.photo_features->has_point[7] = false;
  const KeyframeId with = model.AddKeyframe(keyframe);
  const KeyframeId without = model.AddKeyframe(MakeSyntheticKeyframe(session, 1, SmallKeyframes()));
  // Extracted and nothing found (a bare wall): stored empty, so nobody extracts them again.
  KeyframeRecord bare = MakeSyntheticKeyframe(session, 2, SmallKeyframes());
  bare.photo_features = Features();
  const KeyframeId empty = model.AddKeyframe(bare);
  EXPECT_EQ(model.NumKeyframesWithPhotoFeatures(), 2);
  EXPECT_TRUE(model.HasPhotoFeatures(with));
  EXPECT_FALSE(model.HasPhotoFeatures(without));
  EXPECT_TRUE(model.HasPhotoFeatures(empty));
  ASSERT_TRUE(model.LoadPhotoFeatures(empty).has_value());
  EXPECT_EQ(model.LoadPhotoFeatures(empty)->size(), 0u);
  const std::optional<Features> stored = model.LoadPhotoFeatures(with);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(stored->descriptors.type(), CV_8U);
  EXPECT_EQ(cv::norm(stored->descriptors, keyframe.photo_features->descriptors, cv::NORM_INF), 0.0);
  EXPECT_FALSE(stored->has_point[7]);
  EXPECT_EQ(stored->NumPoints(), 49u);
  EXPECT_FALSE(model.LoadPhotoFeatures(without).has_value());
  // The ORB features are untouched.
  EXPECT_EQ(model.LoadFeatures(with).descriptors.cols, keyframe.features.descriptors.cols);

  Features later = *keyframe.photo_features;
  later.descriptors.setTo(cv::Scalar(3));
  model.SetPhotoFeatures(without, later);
  model.SetPhotoFeatures(with, later);  // replaces
  EXPECT_EQ(model.NumKeyframesWithPhotoFeatures(), 3);
  EXPECT_EQ(cv::norm(model.LoadPhotoFeatures(with)->descriptors, later.descriptors, cv::NORM_INF),
            0.0);
  EXPECT_THROW(model.SetPhotoFeatures(KeyframeId(999), later), Error);
  Features inconsistent = later;
  inconsistent.points_cam.clear();
  inconsistent.has_point.clear();
  EXPECT_THROW(model.SetPhotoFeatures(with, inconsistent), Error);
}

TEST(Model, AKeyframeWithoutDepthPointsRoundTripsWithoutThem) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  KeyframeRecord keyframe = MakeSyntheticKeyframe(session, 0, SmallKeyframes());
  keyframe.features.points_cam.clear();
  keyframe.features.has_point.clear();
  const Features features = model.LoadFeatures(model.AddKeyframe(keyframe));
  EXPECT_EQ(features.size(), 50u);
  EXPECT_TRUE(features.points_cam.empty());
  EXPECT_EQ(features.NumPoints(), 0u);
}

TEST(Model, BadKeyframesAreRejectedAndLeaveNothingBehind) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  KeyframeRecord keyframe = MakeSyntheticKeyframe(session, 0, SmallKeyframes());
  LinkRecord dangling;
  dangling.from = KeyframeId(999);  // no such keyframe: the foreign key fails mid-transaction
  keyframe.links.push_back(dangling);
  EXPECT_THROW(model.AddKeyframe(keyframe), Error);
  EXPECT_EQ(model.NumKeyframes(), 0);
  EXPECT_TRUE(model.Links().empty());

  KeyframeRecord mismatched = MakeSyntheticKeyframe(session, 1, SmallKeyframes());
  mismatched.features.points_cam.pop_back();
  mismatched.features.has_point.pop_back();
  EXPECT_THROW(model.AddKeyframe(mismatched), Error);
  KeyframeRecord unflagged = MakeSyntheticKeyframe(session, 2, SmallKeyframes());
  unflagged.features.has_point.pop_back();
  EXPECT_THROW(model.AddKeyframe(unflagged), Error);
  KeyframeRecord undescribed = MakeSyntheticKeyframe(session, 3, SmallKeyframes());
  undescribed.features.descriptors = cv::Mat();  // allowed, but the points must still match
  undescribed.features.points_cam.pop_back();
  undescribed.features.has_point.pop_back();
  EXPECT_THROW(model.AddKeyframe(undescribed), Error);
  EXPECT_EQ(model.NumKeyframes(), 0);
}

TEST(Model, UpdatePosesIsAllOrNothingAndLabelsFollowKeyframes) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  const KeyframeId a = model.AddKeyframe(MakeSyntheticKeyframe(session, 0, SmallKeyframes()));
  const KeyframeId b = model.AddKeyframe(MakeSyntheticKeyframe(session, 1, SmallKeyframes()));

  LabelRecord lamp;
  lamp.name = "lamp-3f";
  lamp.type = "lamp";
  LabelPoint clicked;
  clicked.source = LabelPointSource::kKeyframePixel;
  clicked.keyframe = b;
  clicked.pixel = Eigen::Vector2d(10, 20);
  clicked.cam_point = Eigen::Vector3d(0.5, -0.25, 2.0);
  clicked.world = Eigen::Vector3d(0.6, -0.25, 2.0);
  lamp.points.push_back(clicked);
  LabelPoint typed;
  typed.world = Eigen::Vector3d(5, 6, 7);
  lamp.points.push_back(typed);
  model.AddLabel(lamp);

  const Eigen::Isometry3d moved = MakePose(0.5, {3.0, 0.0, 1.0});
  // One bad id aborts the whole update.
  EXPECT_THROW(model.UpdatePoses({{a, moved}, {KeyframeId(77), moved}}), Error);
  EXPECT_TRUE(model.Keyframe(a).world_from_cam.isApprox(Eigen::Isometry3d::Identity()));

  model.UpdatePoses({{a, moved}, {b, moved}});
  EXPECT_TRUE(model.Keyframe(b).world_from_cam.isApprox(moved, 1e-12));
  // Odometry is the raw estimate: optimisation leaves it.
  EXPECT_NEAR(model.Keyframe(b).odom_world_from_cam.translation().x(), 0.1, 1e-12);

  const std::optional<LabelRecord> found = model.FindLabel("lamp-3f");
  ASSERT_TRUE(found);
  ASSERT_EQ(found->points.size(), 2u);
  EXPECT_TRUE(found->points[0].world.isApprox(moved * clicked.cam_point, 1e-12));
  EXPECT_EQ(found->points[0].keyframe, b);
  EXPECT_EQ(found->points[0].pixel, clicked.pixel);
  EXPECT_EQ(found->points[1].world, typed.world);
  EXPECT_EQ(found->points[1].source, LabelPointSource::kTyped);
}

TEST(Model, SyntheticViewsRoundTripFollowTheirKeyframeAndStayOutOfTheMap) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  SyntheticKeyframeOptions medium = SmallKeyframes();
  medium.width = 320;
  medium.height = 240;
  const KeyframeRecord source = MakeSyntheticKeyframe(session, 0, medium);
  const KeyframeId a = model.AddKeyframe(source);
  LabelRecord lamp;
  lamp.name = "lamp";
  lamp.points.resize(1);
  const LabelId lamp_id = model.AddLabel(lamp);

  SyntheticViewRecord view;
  view.source = a;
  view.label = lamp_id;
  view.source_from_cam = MakePose(0.4, {0.5, 0.0, -1.0});
  view.intrinsics = source.intrinsics;
  view.intrinsics.width = 320;
  view.intrinsics.height = 240;
  view.color = source.color;
  view.features = source.features;
  const SyntheticViewId id = model.AddSyntheticView(view);
  EXPECT_TRUE(id.valid());
  EXPECT_EQ(model.NumSyntheticViews(), 1);
  // Not a keyframe: mapping, info's keyframe counts and the pose graph never see it.
  EXPECT_EQ(model.NumKeyframes(), 1);
  const ModelSummary summary = model.Summary();
  EXPECT_EQ(summary.synthetic_views, 1);
  EXPECT_GT(summary.synthetic_view_bytes, 0);
  EXPECT_LT(summary.synthetic_view_bytes, summary.size_bytes == 0 ? INT64_MAX : summary.size_bytes);

  std::vector<SyntheticViewRecord> read = model.SyntheticViews();
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].id, id);
  EXPECT_EQ(read[0].source, a);
  EXPECT_EQ(read[0].label, lamp_id);
  EXPECT_TRUE(read[0].source_from_cam.isApprox(view.source_from_cam, 1e-12));
  EXPECT_TRUE(read[0].world_from_cam.isApprox(view.source_from_cam, 1e-12));  // source at origin
  EXPECT_EQ(read[0].intrinsics.width, 320);
  EXPECT_GT(read[0].color_bytes, 0);
  ASSERT_EQ(read[0].features.size(), source.features.size());
  EXPECT_EQ(cv::norm(read[0].features.descriptors, source.features.descriptors, cv::NORM_INF), 0);
  EXPECT_EQ(read[0].features.NumPoints(), source.features.NumPoints());
  EXPECT_EQ(model.LoadSyntheticColor(id).size(), source.color.size());

  // A loop closure that moves the source keyframe moves its views with it.
  const Eigen::Isometry3d moved = MakePose(0.2, {3.0, 1.0, 0.0});
  model.UpdatePoses({{a, moved}});
  read = model.SyntheticViews();
  EXPECT_TRUE(read[0].world_from_cam.isApprox(moved * view.source_from_cam, 1e-12));

  // Deleting the label keeps the view (its features still help), without the label.
  model.DeleteLabel(lamp_id);
  EXPECT_FALSE(model.SyntheticViews()[0].label.valid());

  // Bad views are refused and leave nothing behind.
  SyntheticViewRecord orphan = view;
  orphan.source = KeyframeId();
  EXPECT_THROW(model.AddSyntheticView(orphan), Error);
  SyntheticViewRecord missing_source = view;
  missing_source.source = KeyframeId(99);
  EXPECT_THROW(model.AddSyntheticView(missing_source), Error);
  SyntheticViewRecord wrong_size = view;
  wrong_size.intrinsics.width = 100;
  EXPECT_THROW(model.AddSyntheticView(wrong_size), Error);
  SyntheticViewRecord no_points = view;
  no_points.features.points_cam.clear();
  no_points.features.has_point.clear();
  EXPECT_THROW(model.AddSyntheticView(no_points), Error);
  EXPECT_EQ(model.NumSyntheticViews(), 1);
  EXPECT_THROW(model.LoadSyntheticColor(SyntheticViewId(42)), Error);

  // Replacing: the old views go only once the new one is written.
  SyntheticViewRecord unlabelled = view;
  unlabelled.label = LabelId();  // the lamp was deleted above
  const SyntheticViewId newer = model.AddSyntheticView(unlabelled);
  EXPECT_EQ(model.DeleteSyntheticViews(id), 1);
  ASSERT_EQ(model.SyntheticViews().size(), 1u);
  EXPECT_EQ(model.SyntheticViews()[0].id, newer);
  EXPECT_EQ(model.DeleteSyntheticViews(), 1);
  EXPECT_TRUE(model.SyntheticViews().empty());
  EXPECT_EQ(model.IntegrityCheck(), "ok");
}

TEST(Model, LabelCrud) {
  Model model = Model::Open(":memory:");
  LabelRecord projector;
  projector.name = "projector";
  projector.type = "projector";
  LabelPoint point;
  point.world = Eigen::Vector3d(1, 2, 3);
  point.source = LabelPointSource::kImportedFile;
  point.file = "projector.txt";
  projector.points = {point};
  const LabelId id = model.AddLabel(projector);
  EXPECT_THROW(model.AddLabel(projector), Error);  // names are unique
  LabelRecord empty;
  empty.name = "nothing";
  EXPECT_THROW(model.AddLabel(empty), Error);

  LabelRecord changed = *model.FindLabel("projector");
  EXPECT_EQ(changed.id, id);
  EXPECT_GT(changed.created_ns, 0);
  EXPECT_EQ(changed.points[0].file, "projector.txt");
  changed.type = "beamer";
  changed.points.push_back(point);
  changed.points.back().world = Eigen::Vector3d(4, 5, 6);
  model.UpdateLabel(changed);
  const LabelRecord updated = *model.FindLabel("projector");
  EXPECT_EQ(updated.type, "beamer");
  EXPECT_EQ(updated.points.size(), 2u);
  EXPECT_GE(updated.updated_ns, updated.created_ns);
  EXPECT_EQ(model.Labels().size(), 1u);
  model.DeleteLabel(id);
  EXPECT_FALSE(model.FindLabel("projector"));
  EXPECT_THROW(model.DeleteLabel(id), Error);
}

TEST(Model, SessionsEndAndCrashedOnesBecomeInterrupted) {
  Model model = Model::Open(":memory:");
  const SessionId first = model.BeginSession({});
  const SessionId second = model.BeginSession({});
  const SessionId third = model.BeginSession({});
  model.EndSession(first, SessionEnd::kResumedInto, 5, second);
  model.EndSession(second, SessionEnd::kFinished, 9);
  EXPECT_THROW(model.EndSession(first, SessionEnd::kResumedInto, 5), Error);
  EXPECT_EQ(model.MarkRunningSessionsInterrupted(11), 1);
  const std::vector<SessionRecord> sessions = model.Sessions();
  ASSERT_EQ(sessions.size(), 3u);
  EXPECT_EQ(sessions[0].end_state, SessionEnd::kResumedInto);
  EXPECT_EQ(sessions[0].resumed_into, second);
  EXPECT_EQ(sessions[1].end_state, SessionEnd::kFinished);
  EXPECT_EQ(sessions[2].id, third);
  EXPECT_EQ(sessions[2].end_state, SessionEnd::kInterrupted);
  EXPECT_EQ(sessions[2].end_time_ns, 11);
}

// A run that mapped nothing removes its session; one with a keyframe, or resumed into, stays.
TEST(Model, DeletesOnlyAnEmptySession) {
  Model model = Model::Open(":memory:");
  const SessionId mapped = model.BeginSession({});
  model.AddKeyframe(MakeSyntheticKeyframe(mapped, 0, SmallKeyframes()));
  const SessionId resumed = model.BeginSession({});
  const SessionId empty = model.BeginSession({});
  model.EndSession(resumed, SessionEnd::kResumedInto, 5, mapped);
  model.EndSession(empty, SessionEnd::kFinished, 9);
  const SessionId target = model.BeginSession({});
  model.EndSession(model.BeginSession({}), SessionEnd::kResumedInto, 5, target);
  EXPECT_FALSE(model.DeleteEmptySession(mapped));
  EXPECT_FALSE(model.DeleteEmptySession(target));
  EXPECT_TRUE(model.DeleteEmptySession(empty));
  EXPECT_FALSE(model.DeleteEmptySession(empty));
  EXPECT_EQ(model.Sessions().size(), 4u);
}

TEST(Model, SummaryCountsLinksSegmentsAndBoundingBox) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  std::vector<KeyframeId> ids;
  for (int i = 0; i < 5; ++i) {
    KeyframeRecord keyframe = MakeSyntheticKeyframe(session, i, SmallKeyframes());
    // Keyframe 3 starts a new segment (tracking lost): no odometry link to 2.
    if (i > 0 && i != 3) {
      LinkRecord link;
      link.from = ids.back();
      keyframe.links.push_back(link);
    }
    ids.push_back(model.AddKeyframe(keyframe));
  }
  EXPECT_EQ(model.Summary().segments, 2);
  EXPECT_EQ(model.Summary().largest_segment_keyframes, 3);  // 0-1-2, then 3-4
  LinkRecord loop;
  loop.from = ids[4];
  loop.to = ids[0];
  loop.type = LinkType::kLoopClosure;
  model.AddLink(loop);
  const ModelSummary summary = model.Summary();
  EXPECT_EQ(summary.sessions, 1);
  EXPECT_EQ(summary.keyframes, 5);
  EXPECT_EQ(summary.odometry_links, 3);
  EXPECT_EQ(summary.loop_closures, 1);
  EXPECT_EQ(summary.segments, 1);
  EXPECT_EQ(summary.largest_segment_keyframes, 5);
  EXPECT_TRUE(summary.has_bounding_box);
  EXPECT_NEAR(summary.bbox_max.x(), 0.4, 1e-12);
  EXPECT_NEAR(summary.bbox_min.x(), 0.0, 1e-12);
  EXPECT_GT(summary.size_bytes, 0);
  EXPECT_EQ(summary.schema_version, Model::LatestSchemaVersion());
}

TEST(Model, ALinkSwitchedOffByThePoseGraphStaysOff) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  std::vector<KeyframeId> ids;
  for (int i = 0; i < 4; ++i) {
    KeyframeRecord keyframe = MakeSyntheticKeyframe(session, i, SmallKeyframes());
    if (i > 0) {
      LinkRecord link;
      link.from = ids.back();
      keyframe.links.push_back(link);
    }
    if (i == 3) {  // a loop rejected in the step that found it is stored switched off
      LinkRecord rejected;
      rejected.from = ids[0];
      rejected.type = LinkType::kLoopClosure;
      rejected.active = false;
      keyframe.links.push_back(rejected);
    }
    ids.push_back(model.AddKeyframe(keyframe));
  }
  LinkRecord loop;
  loop.from = ids[3];
  loop.to = ids[1];
  loop.type = LinkType::kLoopClosure;
  model.AddLink(loop);
  EXPECT_EQ(model.Summary().loop_closures, 1);
  EXPECT_EQ(model.Summary().inactive_links, 1);

  // A later optimisation switches the loop off, in the same transaction as its poses.
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.translation() = Eigen::Vector3d(7.0, 0.0, 0.0);
  model.UpdateGraph({{ids[2], moved}}, {{ids[3], ids[1], LinkType::kLoopClosure}});
  int active_loops = 0;
  for (const LinkRecord& link : model.Links()) {
    if (link.type == LinkType::kLoopClosure) active_loops += link.active;
    if (link.type == LinkType::kOdometry) {
      EXPECT_TRUE(link.active);
    }
  }
  EXPECT_EQ(active_loops, 0);
  const ModelSummary summary = model.Summary();
  EXPECT_EQ(summary.loop_closures, 0);
  EXPECT_EQ(summary.inactive_links, 2);
  EXPECT_EQ(summary.odometry_links, 3);
  EXPECT_NEAR(model.Keyframe(ids[2]).world_from_cam.translation().x(), 7.0, 1e-12);

  // The end's solve judges it again and switches it back on, with its poses.
  model.UpdateGraph({{ids[2], moved}}, {}, {{ids[3], ids[1], LinkType::kLoopClosure}});
  EXPECT_EQ(model.Summary().loop_closures, 1);
  EXPECT_EQ(model.Summary().inactive_links, 1);
  model.UpdateGraph({{ids[2], moved}}, {{ids[3], ids[1], LinkType::kLoopClosure}});

  // A link the model does not hold: nothing changes, not even the poses.
  Eigen::Isometry3d elsewhere = Eigen::Isometry3d::Identity();
  elsewhere.translation() = Eigen::Vector3d(-3.0, 0.0, 0.0);
  EXPECT_THROW(model.UpdateGraph({{ids[2], elsewhere}}, {{ids[0], ids[2], LinkType::kUser}}),
               Error);
  EXPECT_NEAR(model.Keyframe(ids[2]).world_from_cam.translation().x(), 7.0, 1e-12);
}

TEST(Model, AKeyframeRevisesAStoredLinkInItsTransaction) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  std::vector<KeyframeId> ids;
  for (int i = 0; i < 2; ++i) {
    KeyframeRecord keyframe = MakeSyntheticKeyframe(session, i, SmallKeyframes());
    if (i > 0) {
      LinkRecord prior;
      prior.from = ids.back();
      prior.type = LinkType::kPrior;
      prior.to_in_from = MakePose(0.6, Eigen::Vector3d(0.5, 0.0, 0.0));
      keyframe.links.push_back(prior);
    }
    ids.push_back(model.AddKeyframe(keyframe));
  }
  // The next keyframe measured the motion after the blind one: the prior is bridged.
  LinkRecord bridged;
  bridged.from = ids[0];
  bridged.to = ids[1];
  bridged.type = LinkType::kPrior;
  bridged.to_in_from = MakePose(0.3, Eigen::Vector3d(0.4, 0.1, 0.0));
  bridged.information = 4.0 * Matrix6d::Identity();
  KeyframeRecord next = MakeSyntheticKeyframe(session, 2, SmallKeyframes());
  next.revised_links.push_back(bridged);
  ids.push_back(model.AddKeyframe(next));
  const auto stored_prior = [&model] {
    for (const LinkRecord& link : model.Links()) {
      if (link.type == LinkType::kPrior) return link;
    }
    ADD_FAILURE() << "no prior link";
    return LinkRecord();
  };
  EXPECT_TRUE(stored_prior().to_in_from.isApprox(bridged.to_in_from, 1e-12));
  EXPECT_EQ(stored_prior().information(0, 0), 4.0);
  EXPECT_EQ(model.Links().size(), 1u);

  // A revision of a link the model does not hold: neither the keyframe nor anything else stored.
  LinkRecord missing = bridged;
  missing.from = ids[1];
  missing.to = ids[2];
  missing.information = Matrix6d::Identity();
  KeyframeRecord last = MakeSyntheticKeyframe(session, 3, SmallKeyframes());
  last.revised_links = {bridged, missing};
  last.revised_links[0].information = 9.0 * Matrix6d::Identity();
  EXPECT_THROW(model.AddKeyframe(last), Error);
  EXPECT_EQ(model.Keyframes().size(), 3u);
  EXPECT_EQ(stored_prior().information(0, 0), 4.0);
}

TEST(Model, VocabularyRoundTrip) {
  Model model = Model::Open(":memory:");
  EXPECT_FALSE(model.LoadVocabulary());
  model.SetVocabulary("dbow3", {1, 2, 3});
  model.SetVocabulary("dbow3", {4, 5});
  const auto vocabulary = model.LoadVocabulary();
  ASSERT_TRUE(vocabulary);
  EXPECT_EQ(vocabulary->first, "dbow3");
  EXPECT_EQ(vocabulary->second, (std::vector<uint8_t>{4, 5}));
}

TEST(Model, ReopensFileInWalModeAndReadOnly) {
  const std::string path = testing::MakeTempDir("store_reopen") + "/model.db";
  {
    Model model = Model::Open(path);
    model.AddKeyframe(MakeSyntheticKeyframe(model.BeginSession({}), 0, SmallKeyframes()));
  }
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* stmt = nullptr;
    sqlite3_prepare_v2(db, "PRAGMA journal_mode", -1, &stmt, nullptr);
    ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
    EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0)), "wal");
    sqlite3_finalize(stmt);
    sqlite3_close(db);
  }
  ModelOptions read_only;
  read_only.read_only = true;
  const Model model = Model::Open(path, read_only);
  EXPECT_EQ(model.NumKeyframes(), 1);
  EXPECT_EQ(model.IntegrityCheck(), "ok");
  EXPECT_THROW(const_cast<Model&>(model).BeginSession({}), Error);
  EXPECT_THROW(Model::Open(path + ".missing", read_only), Error);
}

// Builds a model at schema 1 directly, as an older sightmap would have left it.
void MakeVersionOneModel(const std::string& path) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr), SQLITE_OK);
  internal::ApplyMigrations(db, 0, 1);
  ASSERT_EQ(sqlite3_exec(db,
                         "INSERT INTO labels (name, type, created_ns, updated_ns) VALUES "
                         "('old-lamp', 'lamp', 1, 1); COMMIT",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
}

TEST(Model, OlderSchemaIsUpgradedInPlace) {
  ASSERT_GE(Model::LatestSchemaVersion(), 2);
  const std::string path = testing::MakeTempDir("store_migrate") + "/old.db";
  MakeVersionOneModel(path);
  ModelOptions read_only;
  read_only.read_only = true;
  try {
    Model::Open(path, read_only);
    ADD_FAILURE() << "a read-only open of an old model must ask for an upgrade";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("older schema version 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sightmap info --upgrade"), std::string::npos) << e.what();
  }
  Model model = Model::Open(path);
  EXPECT_EQ(model.SchemaVersion(), Model::LatestSchemaVersion());
  model.SetVocabulary("dbow3", {9});                    // the table migration 2 added
  EXPECT_TRUE(model.Links().empty());                   // reads the column migration 3 added
  EXPECT_TRUE(model.SyntheticViews().empty());          // the table migration 5 added
  EXPECT_EQ(model.NumKeyframesWithPhotoFeatures(), 0);  // the table migration 6 added
  EXPECT_EQ(model.IntegrityCheck(), "ok");
  // The data written under schema 1 survived.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  sqlite3_prepare_v2(db, "SELECT group_concat(version) FROM sightmap_schema", -1, &stmt, nullptr);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0)), "1,2,3,4,5,6");
  sqlite3_finalize(stmt);
  sqlite3_close(db);
}

std::string OpenError(const std::string& path, const ModelOptions& options = {}) {
  try {
    Model::Open(path, options);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Model, NewerSchemaIsRefused) {
  const std::string path = testing::MakeTempDir("store_newer") + "/new.db";
  { Model::Open(path); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(db, "INSERT INTO sightmap_schema VALUES (99, 0)", nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(db);
  const std::string message = OpenError(path);
  EXPECT_NE(message.find("schema version 99"), std::string::npos) << message;
  EXPECT_NE(message.find("update sightmap"), std::string::npos) << message;
  EXPECT_EQ(CountLines(message), 0);
}

TEST(Model, NonSqliteFileGivesOneLineError) {
  const std::string path = testing::MakeTempDir("store_notdb") + "/notes.db";
  std::ofstream(path) << "this is a shopping list, not a database\n" << std::string(5000, 'x');
  const std::string message = OpenError(path);
  EXPECT_NE(message.find("not a SQLite database"), std::string::npos) << message;
  EXPECT_EQ(CountLines(message), 0);
  // And the file was not touched.
  EXPECT_EQ(std::filesystem::file_size(path), 5040u);
}

TEST(Model, OtherApplicationsDatabaseGivesOneLineError) {
  const std::string path = testing::MakeTempDir("store_other") + "/places.sqlite";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "CREATE TABLE moz_places (id INTEGER PRIMARY KEY, url TEXT)", nullptr,
                         nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  const std::string message = OpenError(path);
  EXPECT_NE(message.find("another application"), std::string::npos) << message;
  EXPECT_EQ(CountLines(message), 0);
  ModelOptions read_only;
  read_only.read_only = true;
  EXPECT_NE(OpenError(path, read_only).find("another application"), std::string::npos);
}

TEST(Model, ReadOnlyFileGivesOneLineError) {
  const std::string dir = testing::MakeTempDir("store_readonly");
  const std::string path = dir + "/model.db";
  { Model::Open(path); }
  ASSERT_EQ(chmod(path.c_str(), 0444), 0);
  ASSERT_EQ(chmod(dir.c_str(), 0755), 0);
  // Root writes through any mode bits, so the open runs in a child that gives up root first.
  const testing::ChildOutcome outcome = testing::RunInChild([&] {
    if (geteuid() == 0) {
      SIGHTMAP_CHECK(setgid(65534) == 0 && setuid(65534) == 0, "cannot drop root for the test");
    }
    Model::Open(path);
  });
  EXPECT_EQ(outcome.exit_code, 3) << outcome.message;
  EXPECT_NE(outcome.message.find("read-only"), std::string::npos) << outcome.message;
  EXPECT_NE(outcome.message.find("chmod u+w"), std::string::npos) << outcome.message;
  EXPECT_EQ(CountLines(outcome.message), 0);
}

TEST(Model, ModelInAReadOnlyFolderCanStillBeRead) {
  const std::string dir = testing::MakeTempDir("store_readonly_folder");
  const std::string path = dir + "/model.db";
  {
    Model model = Model::Open(path);
    model.AddKeyframe(MakeSyntheticKeyframe(model.BeginSession({}), 0, SmallKeyframes()));
  }
  ASSERT_FALSE(std::filesystem::exists(path + "-wal"));  // merged on close
  ASSERT_EQ(chmod(path.c_str(), 0444), 0);
  ASSERT_EQ(chmod(dir.c_str(), 0555), 0);
  // As in ReadOnlyFileGivesOneLineError: without root, the folder really is read-only.
  const testing::ChildOutcome outcome = testing::RunInChild([&] {
    if (geteuid() == 0) {
      SIGHTMAP_CHECK(setgid(65534) == 0 && setuid(65534) == 0, "cannot drop root for the test");
    }
    ModelOptions read_only;
    read_only.read_only = true;
    const Model model = Model::Open(path, read_only);
    SIGHTMAP_CHECK(model.NumKeyframes() == 1 && model.LoadDepth(model.Keyframes()[0].id).rows == 48,
                   "the read-only model does not read back");
  });
  chmod(dir.c_str(), 0755);
  EXPECT_EQ(outcome.exit_code, 0) << outcome.message;
}

TEST(Model, OptionsAreChecked) {
  ModelOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error));
  options.jpeg_quality = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("jpeg_quality"), std::string::npos);
  EXPECT_THROW(Model::Open(":memory:", options), InvalidArgument);
}

}  // namespace
}  // namespace sightmap::store
