#include "identify/coverage.h"

#include <cmath>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "store/model.h"
#include "store/synthetic_model.h"

namespace sightmap::identify {
namespace {

// A closed room, x in [0, 6], y in [0, 4], z in [0, 3] (z up), seen from inside.
const Eigen::Vector3d kRoomLo(0.0, 0.0, 0.0);
const Eigen::Vector3d kRoomHi(6.0, 4.0, 3.0);
// A thermostat on the east wall (x = 6).
const Eigen::Vector3d kThermostat(5.95, 2.0, 1.5);
const Eigen::Vector3d kUp = Eigen::Vector3d::UnitZ();

// The room's depth [mm] from a camera inside it (`room_from_cam`).
cv::Mat RoomDepth(const Intrinsics& camera, const Eigen::Isometry3d& room_from_cam) {
  cv::Mat depth(camera.height, camera.width, CV_16UC1);
  const Eigen::Vector3d eye = room_from_cam.translation();
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray = camera.Unproject(u, v, 1.0);  // z = 1 in the camera
      const Eigen::Vector3d direction = room_from_cam.linear() * ray;
      double t = std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        if (direction[a] > 1e-12) t = std::min(t, (kRoomHi[a] - eye[a]) / direction[a]);
        if (direction[a] < -1e-12) t = std::min(t, (kRoomLo[a] - eye[a]) / direction[a]);
      }
      depth.at<uint16_t>(v, u) = static_cast<uint16_t>(std::lround(1000.0 * t));
    }
  }
  return depth;
}

class RoomModel {
 public:
  // `world_from_room` places the room in the model's world (a map anchored at a tilted first
  // camera has no z up).
  explicit RoomModel(const Eigen::Isometry3d& world_from_room = Eigen::Isometry3d::Identity())
      : world_from_room_(world_from_room), session_(model_.BeginSession({})) {
    // Cameras at the room's middle looking round it, but not at the thermostat (east, yaw 0):
    // they carve the room's space.
    for (const double yaw_deg : {70.0, 110.0, 150.0, 180.0, 210.0, 250.0, 290.0}) {
      const double yaw = DegToRad(yaw_deg);
      const Eigen::Vector3d eye(3.0, 2.0, 1.5);
      Add(LookAt(eye, eye + Eigen::Vector3d(std::cos(yaw), std::sin(yaw), -0.1), kUp));
    }
    store::LabelRecord label;
    label.name = "thermostat";
    label.type = "thermostat";
    store::LabelPoint point;
    point.world = world_from_room_ * kThermostat;
    label.points.push_back(point);
    model_.AddLabel(label);
  }

  // A keyframe standing `distance_m` from the thermostat towards `bearing_deg` (from +x towards
  // +y), looking at it.
  void AddLookingAtThermostat(double bearing_deg, double distance_m) {
    const double b = DegToRad(bearing_deg);
    const Eigen::Vector3d eye = Eigen::Vector3d(kThermostat.x(), kThermostat.y(), 1.5) +
                                distance_m * Eigen::Vector3d(std::cos(b), std::sin(b), 0.0);
    Add(LookAt(eye, kThermostat, kUp));
  }

  store::Model& model() { return model_; }

 private:
  void Add(const Eigen::Isometry3d& room_from_cam) {
    store::SyntheticKeyframeOptions options;
    options.width = 160;
    options.height = 120;
    options.num_features = 10;
    store::KeyframeRecord record = store::MakeSyntheticKeyframe(session_, index_++, options);
    record.depth = RoomDepth(record.intrinsics, room_from_cam);
    record.world_from_cam = world_from_room_ * room_from_cam;
    record.odom_world_from_cam = record.world_from_cam;
    model_.AddKeyframe(record);
  }

  store::Model model_ = store::Model::Open(":memory:");
  Eigen::Isometry3d world_from_room_;
  SessionId session_;
  int index_ = 0;
};

std::set<int> Sectors(const LabelCoverage& label, bool (*pick)(const SectorCoverage&)) {
  std::set<int> picked;
  for (size_t s = 0; s < label.sectors.size(); ++s) {
    if (pick(label.sectors[s])) picked.insert(static_cast<int>(s));
  }
  return picked;
}

bool IsOpen(const SectorCoverage& sector) { return sector.open; }
bool IsSeen(const SectorCoverage& sector) { return sector.seen(); }

TEST(Coverage, SeesWhereKeyframesStoodAndMissesOpenDirectionsButNotTheWallBehind) {
  RoomModel room;
  room.AddLookingAtThermostat(135.0, 2.0);  // sector 4 of 12: [120, 150)
  room.AddLookingAtThermostat(165.0, 2.5);  // sector 5
  room.AddLookingAtThermostat(195.0, 1.5);  // sector 6
  room.AddLookingAtThermostat(200.0, 3.0);  // sector 6 again, further
  const ModelCoverage coverage = ComputeCoverage(room.model());

  EXPECT_LT((coverage.up - Eigen::Vector3d::UnitZ()).norm(), 0.05) << coverage.up.transpose();
  ASSERT_EQ(coverage.labels.size(), 1u);
  const LabelCoverage& label = coverage.labels[0];
  EXPECT_EQ(label.name, "thermostat");
  ASSERT_EQ(label.sectors.size(), 12u);
  EXPECT_EQ(Sectors(label, IsSeen), (std::set<int>{4, 5, 6}));
  EXPECT_EQ(label.sectors[6].keyframes, 2);
  EXPECT_NEAR(label.sectors[6].nearest_m, 1.5, 1e-6);
  EXPECT_NEAR(label.sectors[6].farthest_m, 3.0, 1e-6);
  EXPECT_EQ(label.keyframes, 4);

  // Into the room (bearings 120-240 degrees) a person can stand and see the thermostat; behind
  // the east wall (bearings within 90 degrees of +x) nobody can.
  const std::set<int> open = Sectors(label, IsOpen);
  for (int s : {4, 5, 6, 7}) EXPECT_TRUE(open.count(s)) << "sector " << s;
  for (int s : {0, 1, 2, 9, 10, 11}) EXPECT_FALSE(open.count(s)) << "sector " << s;
  // Where a person could stand: one of the probed distances (1.5, 2.5, 3.5 m) in open sectors.
  ASSERT_FALSE(label.sectors[7].open_distances_m.empty());
  EXPECT_NEAR(label.sectors[7].open_distances_m.front(), 1.5, 1e-6);
  EXPECT_TRUE(label.sectors[0].open_distances_m.empty());
  EXPECT_EQ(label.open, static_cast<int>(open.size()));
  EXPECT_EQ(label.seen, 3);
  EXPECT_DOUBLE_EQ(label.share(), 3.0 / label.open);
  EXPECT_DOUBLE_EQ(coverage.share(), label.share());
}

TEST(Coverage, KeyframesOutsideTheDistanceBandSeeTheLabelButCoverNoSector) {
  RoomModel room;
  room.AddLookingAtThermostat(180.0, 0.6);  // nearer than the 1 m of the band
  room.AddLookingAtThermostat(180.0, 5.5);  // beyond 4 m
  const ModelCoverage coverage = ComputeCoverage(room.model());
  ASSERT_EQ(coverage.labels.size(), 1u);
  EXPECT_EQ(coverage.labels[0].keyframes, 2);
  EXPECT_EQ(coverage.labels[0].seen, 0);
  EXPECT_GT(coverage.labels[0].open, 0);
  EXPECT_EQ(coverage.share(), 0.0);

  CoverageOptions wide;
  wide.min_distance_m = 0.5;
  wide.max_distance_m = 6.0;
  EXPECT_EQ(ComputeCoverage(room.model(), wide).labels[0].sectors[6].keyframes, 2);
}

TEST(Coverage, AHiddenLabelIsNotSeen) {
  // The thermostat moved 1 m behind the east wall: keyframes look at the wall in front of it.
  RoomModel room;
  room.AddLookingAtThermostat(180.0, 2.0);
  store::LabelRecord label = *room.model().FindLabel("thermostat");
  label.points[0].world = kThermostat + Eigen::Vector3d(1.0, 0.0, 0.0);
  room.model().UpdateLabel(label);
  const ModelCoverage coverage = ComputeCoverage(room.model());
  EXPECT_EQ(coverage.labels[0].keyframes, 0);
  EXPECT_EQ(coverage.labels[0].seen, 0);
  EXPECT_EQ(coverage.labels[0].open, 0);  // nobody can see into the wall
}

TEST(Coverage, AMapAnchoredAtATiltedCameraFindsItsUpAndTheSameCoverage) {
  const Eigen::Isometry3d world_from_room =
      Eigen::Translation3d(0.4, -2.0, 1.0) *
      Eigen::AngleAxisd(1.9, Eigen::Vector3d(0.3, -1.0, 0.4).normalized());
  RoomModel level;
  RoomModel tilted(world_from_room);
  for (RoomModel* room : {&level, &tilted}) {
    room->AddLookingAtThermostat(135.0, 2.0);
    room->AddLookingAtThermostat(195.0, 1.5);
  }
  const ModelCoverage a = ComputeCoverage(level.model());
  const ModelCoverage b = ComputeCoverage(tilted.model());
  // The cameras looking round the room tilt 6 degrees down, so the estimate is a degree or two off
  // the vertical, and off by the same in both worlds.
  EXPECT_LT((a.up - Eigen::Vector3d::UnitZ()).norm(), 0.05) << a.up.transpose();
  EXPECT_LT((b.up - world_from_room.linear() * a.up).norm(), 1e-9);
  EXPECT_NEAR(b.eye_height_m - b.up.dot(world_from_room.translation()), a.eye_height_m, 1e-6);
  EXPECT_EQ(a.labels[0].seen, 2);
  EXPECT_EQ(b.labels[0].seen, 2);
  EXPECT_EQ(b.labels[0].keyframes, a.labels[0].keyframes);
  // Free space is sampled on the world's grid, so a rotated room may differ by a grazing sector.
  EXPECT_NEAR(b.labels[0].open, a.labels[0].open, 1);
}

TEST(Coverage, JsonAndPlanSayTheSame) {
  RoomModel room;
  room.AddLookingAtThermostat(165.0, 2.5);
  const ModelCoverage coverage = ComputeCoverage(room.model());
  const nlohmann::json json = CoverageToJson(coverage);
  EXPECT_DOUBLE_EQ(json["share"].get<double>(), coverage.share());
  EXPECT_EQ(json["seen_sectors"], 1);
  ASSERT_EQ(json["labels"].size(), 1u);
  const nlohmann::json& label = json["labels"][0];
  EXPECT_EQ(label["name"], "thermostat");
  EXPECT_EQ(label["sectors"].size(), 12u);
  EXPECT_EQ(label["sectors"][5]["seen"], true);
  EXPECT_EQ(label["sectors"][5]["keyframes"], 1);
  EXPECT_NEAR(label["sectors"][5]["nearest_m"].get<double>(), 2.5, 1e-6);
  EXPECT_EQ(label["sectors"][0]["open"], false);

  const cv::Mat plan = DrawCoverage(coverage, 400);
  ASSERT_EQ(plan.type(), CV_8UC3);
  EXPECT_EQ(std::max(plan.cols, plan.rows), 400);
  // The room's floor is drawn: walls dark, its inside light grey.
  int dark = 0;
  int green = 0;
  int red = 0;
  for (int r = 0; r < plan.rows; ++r) {
    for (int c = 0; c < plan.cols; ++c) {
      const cv::Vec3b p = plan.at<cv::Vec3b>(r, c);
      dark += p[0] == 70 && p[1] == 70 && p[2] == 70;
      green += p == cv::Vec3b(60, 170, 40);
      red += p == cv::Vec3b(40, 40, 220);
    }
  }
  EXPECT_GT(dark, 100);
  EXPECT_GT(green, 10);   // the one seen sector
  EXPECT_GT(red, green);  // the open sectors not seen
}

TEST(Coverage, APhotoIsCoveredByAKeyframeThatSawItsTargetFromASimilarView) {
  const Intrinsics camera = Intrinsics::FromFieldOfView(640, 480, DegToRad(62.0), 0.0);
  // The photo 2 m in front of the thermostat (which faces -x).
  const Eigen::Isometry3d photo = LookAt({3.95, 2.0, 1.5}, kThermostat, kUp);
  auto keyframe_at = [&](const Eigen::Vector3d& eye, const Eigen::Vector3d& look_at) {
    store::KeyframeInfo keyframe;
    keyframe.world_from_cam = LookAt(eye, look_at, kUp);
    keyframe.intrinsics = camera;
    return std::vector<store::KeyframeInfo>{keyframe};
  };
  auto at_bearing = [&](double deg, double distance) {
    const double a = DegToRad(180.0 + deg);
    return Eigen::Vector3d(kThermostat.x() + distance * std::cos(a),
                           kThermostat.y() + distance * std::sin(a), 1.5);
  };
  // 35 deg off the photo's line of sight: covered; 45 deg: not.
  EXPECT_TRUE(ViewWasSeen(photo, kThermostat, keyframe_at(at_bearing(35, 2.0), kThermostat)));
  EXPECT_FALSE(ViewWasSeen(photo, kThermostat, keyframe_at(at_bearing(45, 2.0), kThermostat)));
  // Within a factor 2 of the photo's 2 m: 3.9 m covered, 4.1 m and 0.9 m not.
  EXPECT_TRUE(ViewWasSeen(photo, kThermostat, keyframe_at(at_bearing(0, 3.9), kThermostat)));
  EXPECT_FALSE(ViewWasSeen(photo, kThermostat, keyframe_at(at_bearing(0, 4.1), kThermostat)));
  EXPECT_FALSE(ViewWasSeen(photo, kThermostat, keyframe_at(at_bearing(0, 0.9), kThermostat)));
  // Standing in the right place but looking away (the target outside its image): not covered.
  EXPECT_FALSE(ViewWasSeen(
      photo, kThermostat,
      keyframe_at(at_bearing(0, 2.0), at_bearing(0, 2.0) + Eigen::Vector3d(0.0, 3.0, 0.0))));
  // The target near its image's edge still counts: 25 deg off its axis (the half field is 31).
  const Eigen::Vector3d eye = at_bearing(0, 2.0);
  const Eigen::Vector3d aside =
      eye + Eigen::AngleAxisd(DegToRad(25.0), Eigen::Vector3d::UnitZ()) * (kThermostat - eye);
  EXPECT_TRUE(ViewWasSeen(photo, kThermostat, keyframe_at(eye, aside)));
  EXPECT_FALSE(ViewWasSeen(photo, kThermostat, {}));
  // The nearest view's angle: the smaller of two keyframes', none beyond the distance factor.
  std::vector<store::KeyframeInfo> two = keyframe_at(at_bearing(50, 2.0), kThermostat);
  two.push_back(keyframe_at(at_bearing(-20, 2.5), kThermostat).front());
  const std::optional<double> angle = NearestViewAngleDeg(photo, kThermostat, two);
  ASSERT_TRUE(angle.has_value());
  EXPECT_NEAR(*angle, 20.0, 0.5);
  EXPECT_FALSE(
      NearestViewAngleDeg(photo, kThermostat, keyframe_at(at_bearing(0, 4.1), kThermostat)));
  EXPECT_FALSE(NearestViewAngleDeg(photo, kThermostat, {}));
  ViewSeenOptions bad;
  bad.max_distance_ratio = 0.5;
  EXPECT_THROW(ViewWasSeen(photo, kThermostat, keyframe_at(eye, kThermostat), bad),
               InvalidArgument);
  // Every keyframe that saw it, by the same rule: 20 and 35 deg off, not 45 deg or 4.1 m away.
  std::vector<store::KeyframeInfo> four = keyframe_at(at_bearing(45, 2.0), kThermostat);
  for (const auto& [bearing, distance] :
       {std::pair(20.0, 2.5), std::pair(0.0, 4.1), std::pair(-35.0, 1.5)}) {
    four.push_back(keyframe_at(at_bearing(bearing, distance), kThermostat).front());
  }
  EXPECT_EQ(KeyframesSeeingView(photo, kThermostat, four), (std::vector<size_t>{1, 3}));
  EXPECT_TRUE(KeyframesSeeingView(photo, kThermostat, {}).empty());
  EXPECT_THROW(KeyframesSeeingView(photo, kThermostat, four, bad), InvalidArgument);
}

TEST(Coverage, RefusesBadOptions) {
  RoomModel room;
  CoverageOptions options;
  options.max_distance_m = options.min_distance_m;
  EXPECT_THROW(ComputeCoverage(room.model(), options), InvalidArgument);
  std::string error;
  options = CoverageOptions();
  options.sectors = 2;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("sectors"), std::string::npos);
}

}  // namespace
}  // namespace sightmap::identify
