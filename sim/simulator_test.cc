#include "sim/simulator.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/rgbd_source.h"
#include "core/check.h"
#include "core/rotation.h"
#include "sim/sim_source.h"
#include "tests/test_data.h"

namespace sightmap::sim {
namespace {

SimulatorOptions FastOptions(TrajectoryKind kind = TrajectoryKind::kHandheld) {
  SimulatorOptions options;
  options.trajectory = kind;
  options.fps = 1.0;
  options.seed = 7;
  return options;
}

bool SameBytes(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() &&
         std::equal(a.datastart, a.dataend, b.datastart);
}

TEST(Simulator, SameOptionsGiveIdenticalBytesAndSeedsDiffer) {
  Simulator first(FastOptions());
  Simulator second(FastOptions());
  // The second simulator renders frame 12 without the frames before it.
  const RgbdFrame a = first.RenderFrame(12);
  const RgbdFrame b = second.RenderFrame(12);
  EXPECT_TRUE(SameBytes(a.color, b.color));
  EXPECT_TRUE(SameBytes(a.depth, b.depth));
  EXPECT_EQ(a.timestamp_ns, 12'000'000'000);
  const std::vector<QueryPhoto> qa = first.MakeQueries(2, QueryOptions());
  const std::vector<QueryPhoto> qb = second.MakeQueries(2, QueryOptions());
  ASSERT_EQ(qa.size(), 2u);
  for (size_t i = 0; i < qa.size(); ++i) {
    EXPECT_TRUE(SameBytes(qa[i].image, qb[i].image));
    EXPECT_TRUE(qa[i].world_from_cam.isApprox(qb[i].world_from_cam, 0.0));
  }
  SimulatorOptions other = FastOptions();
  other.seed = 8;
  Simulator third(other);
  const RgbdFrame c = third.RenderFrame(12);
  EXPECT_FALSE(SameBytes(a.color, c.color));
}

// Every valid depth pixel, back-projected with the ground-truth pose, lies on a scene surface:
// the ray through the pixel hits the scene at the measured depth within the noise model.
TEST(Simulator, DepthBackProjectedWithGroundTruthLandsOnTheScene) {
  for (const TrajectoryKind kind : {TrajectoryKind::kHandheld, TrajectoryKind::kRobot}) {
    Simulator simulator(FastOptions(kind));
    const Intrinsics& k = simulator.options().camera;
    const DepthSensorOptions& noise = simulator.options().depth;
    for (const int64_t index : {5, 60, 130}) {
      const RgbdFrame frame = simulator.RenderFrame(index);
      ASSERT_TRUE(frame.world_from_cam_gt.has_value());
      const Eigen::Isometry3d& world_from_cam = *frame.world_from_cam_gt;
      int checked = 0, within = 0;
      for (int v = 5; v < k.height; v += 12) {
        for (int u = 11; u < k.width; u += 12) {
          const double z = frame.DepthMeters(u, v);
          if (z <= 0.0) continue;
          const Eigen::Vector3d ray_world = world_from_cam.linear() * k.Unproject(u, v, 1.0);
          const auto hit = simulator.scene().Raycast(world_from_cam.translation(), ray_world, 50.0);
          ASSERT_TRUE(hit.has_value()) << "pixel " << u << "," << v << " has depth but no surface";
          ++checked;
          // The ray direction has unit z in the camera, so the hit parameter is the true depth.
          const double tolerance =
              4.0 * noise.DepthStdDev(hit->first) + noise.DepthStep(hit->first) + 0.002;
          within += std::abs(hit->first - z) <= tolerance;
        }
      }
      ASSERT_GT(checked, 500) << "frame " << index;
      // Pixels on an edge can see the ray hit the other side of a box edge.
      EXPECT_GT(static_cast<double>(within) / checked, 0.99)
          << ToString(kind) << " frame " << index;
    }
  }
}

TEST(Simulator, TrajectoriesStayInTheirEnvelopeVisitEveryRoomAndLoop) {
  const Scene scene = LoadScene("office");
  for (const TrajectoryKind kind : {TrajectoryKind::kHandheld, TrajectoryKind::kRobot}) {
    TrajectoryOptions options;
    options.kind = kind;
    options.seed = 3;
    const Trajectory trajectory(scene, options);
    std::set<std::string> rooms;
    std::vector<Eigen::Vector3d> positions;
    double path = 0.0;
    bool loop = false;
    const double duration = 300.0;
    for (double t = 0.0; t <= duration; t += 1.0 / 30.0) {
      const Eigen::Isometry3d pose = trajectory.WorldFromCam(t);
      const Eigen::Vector3d p = pose.translation();
      if (!positions.empty()) path += (p - positions.back()).head<2>().norm();
      const Eigen::Vector3d forward = pose.linear().col(2);
      const Eigen::Vector3d right = pose.linear().col(0);
      const double pitch = std::asin(forward.z());
      const double roll = std::asin(-right.z() / std::cos(pitch));
      if (kind == TrajectoryKind::kRobot) {
        ASSERT_NEAR(p.z(), 0.75, 1e-9);
        ASSERT_NEAR(pitch, 0.0, 1e-9);
        ASSERT_NEAR(roll, 0.0, 1e-9);
      } else {
        ASSERT_GE(p.z(), 1.4);
        ASSERT_LE(p.z(), 1.7);
        ASSERT_LE(std::abs(pitch), DegToRad(15.0) + 1e-9);
        ASSERT_LE(std::abs(roll), DegToRad(5.0) + 1e-9);
      }
      ASSERT_TRUE(scene.IsFree(p, 0.05))
          << "camera inside an object at t=" << t << ": " << p.transpose();
      if (const Room* room = scene.RoomAt(p.head<2>())) rooms.insert(room->name);
      // A loop: back within 0.5 m of a place visited more than 60 s earlier.
      const size_t frames_60s = 60 * 30;
      for (size_t i = 0; !loop && i + frames_60s < positions.size(); i += 15) {
        loop = (positions[i] - p).head<2>().norm() < 0.5;
      }
      positions.push_back(p);
    }
    EXPECT_EQ(rooms.size(), scene.rooms.size()) << ToString(kind);
    EXPECT_TRUE(loop) << ToString(kind);
    const double expected_speed = kind == TrajectoryKind::kRobot ? 0.4 : 0.5;
    EXPECT_NEAR(path / duration, expected_speed, 0.15 * expected_speed) << ToString(kind);
  }
}

TEST(Simulator, SessionsMoveChairsChangeLightAndStartElsewhere) {
  SimulatorOptions one = FastOptions();
  SimulatorOptions two = FastOptions();
  two.session = 2;
  Simulator a(one);
  Simulator b(two);
  int moved = 0;
  for (size_t i = 0; i < a.scene().boxes.size(); ++i) {
    const double shift = (a.scene().boxes[i].center - b.scene().boxes[i].center).norm();
    if (a.scene().boxes[i].group.empty()) {
      EXPECT_EQ(shift, 0.0) << a.scene().boxes[i].name;
    } else {
      moved += shift > 0.01;
    }
  }
  EXPECT_GT(moved, 10);
  EXPECT_GT((a.WorldFromCam(0).translation() - b.WorldFromCam(0).translation()).norm(), 2.0);
  EXPECT_NE(a.renderer().options().ambient, b.renderer().options().ambient);
}

// A hand-built scene: a wall hides one appliance, another sits half outside the image, one is in
// full view and one is behind the camera.
TEST(Simulator, QueryTypesOnHandBuiltCases) {
  const std::string dir = testing::MakeTempDir("query_types");
  const std::string scene_file = dir + "/scene.json";
  std::ofstream(scene_file) << R"({
    "name": "test", "materials": {"grey": {"color": [0.5, 0.5, 0.5]}},
    "boxes": [{"name": "wall_middle", "center": [3, 0, 1.5], "size": [0.1, 1.0, 3], "material": "grey"}],
    "appliances": [
      {"name": "hidden", "type": "lamp", "points": [[4, 0, 1.5]],
       "boxes": [{"center": [4, 0, 1.5], "size": [0.2, 0.4, 0.4], "material": "grey"}]},
      {"name": "in_view", "type": "tv", "points": [[4, 1.2, 1.5]],
       "boxes": [{"center": [4, 1.2, 1.5], "size": [0.2, 0.4, 0.4], "material": "grey"}]},
      {"name": "cut", "type": "printer", "points": [[4, -2.5, 1.5]],
       "boxes": [{"center": [4, -2.5, 1.5], "size": [0.2, 0.6, 0.4], "material": "grey"}]},
      {"name": "behind", "type": "thermostat", "points": [[-3, 0, 1.5]],
       "boxes": [{"center": [-3, 0, 1.5], "size": [0.2, 0.4, 0.4], "material": "grey"}]}],
    "rooms": [{"name": "room", "min": [-5, -5], "max": [5, 5]}],
    "tour": [[0, 0], [1, 0], [1, 1]]})";
  SimulatorOptions options = FastOptions();
  options.scene = scene_file;
  Simulator simulator(options);
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = k.fy = 500;
  k.cx = 319.5;
  k.cy = 239.5;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear() = WorldFromCamRotation(0.0, 0.0, 0.0);  // looking along +x
  world_from_cam.translation() = Eigen::Vector3d(0, 0, 1.5);
  // "cut" (world y -2.2 .. -2.8 at x 3.9) projects to u = 319.5 + 500 * y_right / 3.9, i.e.
  // 601 .. 679: the image ends at 640, so about half of it is outside.
  const QueryPhoto photo = simulator.RenderQuery(k, world_from_cam, VisibilityThresholds(), 1);
  ASSERT_EQ(photo.visibility.size(), 4u);
  EXPECT_EQ(photo.visibility[0].type, VisibilityType::kOccluded);
  EXPECT_EQ(photo.visibility[0].visible_px, 0);
  EXPECT_GT(photo.visibility[0].in_image_px, 50);
  EXPECT_EQ(photo.visibility[1].type, VisibilityType::kVisible);
  EXPECT_EQ(photo.visibility[2].type, VisibilityType::kPartiallyVisible);
  const double share =
      static_cast<double>(photo.visibility[2].in_image_px) / photo.visibility[2].footprint_px;
  EXPECT_NEAR(share, 0.5, 0.1);
  EXPECT_EQ(photo.visibility[3].type, VisibilityType::kNotVisible);
  EXPECT_EQ(photo.image.cols, 640);
}

TEST(Simulator, APhotoShowsAnApplianceVisibleOrPartlyVisibleNotOneHiddenOrOutOfView) {
  QueryPhoto photo;
  const VisibilityType types[] = {VisibilityType::kVisible, VisibilityType::kPartiallyVisible,
                                  VisibilityType::kOccluded, VisibilityType::kNotVisible};
  for (int id = 1; id <= 4; ++id) {
    ApplianceVisibility visibility;
    visibility.appliance_id = id;
    visibility.type = types[id - 1];
    photo.visibility.push_back(visibility);
  }
  EXPECT_TRUE(ShowsAppliance(photo.visibility, 1));
  EXPECT_TRUE(ShowsAppliance(photo.visibility, 2));
  EXPECT_FALSE(ShowsAppliance(photo.visibility, 3));
  EXPECT_FALSE(ShowsAppliance(photo.visibility, 4));
  EXPECT_FALSE(ShowsAppliance(photo.visibility, 5));  // not in the scene
}

// Photos whose target shows (visible or partly).
int ShownTargets(const std::vector<QueryPhoto>& photos) {
  int shown = 0;
  for (const QueryPhoto& photo : photos)
    shown += ShowsAppliance(photo.visibility, photo.target_appliance);
  return shown;
}

TEST(Simulator, PhonePhotosAreAimedAtAppliancesWithinTheEnvelope) {
  Simulator simulator(FastOptions());
  QueryOptions options;
  options.width = 640;
  options.height = 480;
  const std::vector<QueryPhoto> photos = simulator.MakeQueries(12, options);
  ASSERT_EQ(photos.size(), 12u);
  int occluders = 0;
  std::set<int> targets;
  for (const QueryPhoto& photo : photos) {
    const Appliance& target =
        simulator.scene().appliances[static_cast<size_t>(photo.target_appliance - 1)];
    const Eigen::Vector3d p = photo.world_from_cam.translation();
    const double distance = (target.points.front() - p).head<2>().norm();
    EXPECT_GE(distance, options.min_distance_m - 1e-9);
    EXPECT_LE(distance, options.max_distance_m + 1e-9);
    EXPECT_GE(p.z(), options.min_height_m);
    EXPECT_LE(p.z(), options.max_height_m);
    EXPECT_NEAR(photo.intrinsics.HorizontalFieldOfView(), DegToRad(65.0), 1e-6);
    occluders += photo.with_occluder;
    targets.insert(photo.target_appliance);
  }
  EXPECT_EQ(targets.size(), 12u);
  // A person photographs what they can see: furniture may stand on the line of sight, but the
  // target shows in every photo.
  EXPECT_EQ(ShownTargets(photos), 12);
  EXPECT_GE(occluders, 1);
}

// Furniture on the line of sight may hide the whole target: such a photo is drawn again from a
// stream of its own, and every other photo stays byte for byte what it was.
TEST(Simulator, APhotoThatHidesItsTargetIsDrawnAgainAndLeavesTheOthersAlone) {
  QueryOptions options;
  options.width = 320;
  options.height = 240;
  options.occluder_share = 0.5;  // half of the photos with furniture on the line of sight
  Simulator simulator(FastOptions());
  options.max_hidden_target_redraws = 0;
  const std::vector<QueryPhoto> as_drawn = simulator.MakeQueries(21, options);
  options.max_hidden_target_redraws = QueryOptions().max_hidden_target_redraws;
  const std::vector<QueryPhoto> redrawn = simulator.MakeQueries(21, options);
  const int hidden = 21 - ShownTargets(as_drawn);
  std::printf("targets hidden: %d of 21 as drawn, %d redrawn\n", hidden,
              21 - ShownTargets(redrawn));
  ASSERT_GE(hidden, 1) << "the test needs a photo whose target the furniture hides";
  EXPECT_EQ(ShownTargets(redrawn), 21);
  for (size_t i = 0; i < as_drawn.size(); ++i) {
    const VisibilityType type =
        as_drawn[i].visibility[static_cast<size_t>(as_drawn[i].target_appliance - 1)].type;
    if (type != VisibilityType::kVisible && type != VisibilityType::kPartiallyVisible) continue;
    EXPECT_TRUE(as_drawn[i].world_from_cam.isApprox(redrawn[i].world_from_cam)) << i;
    EXPECT_EQ(cv::norm(as_drawn[i].image, redrawn[i].image, cv::NORM_INF), 0.0) << i;
  }
  std::string error;
  options.max_hidden_target_redraws = 256;  // would take the next photo's streams
  EXPECT_FALSE(options.Check(&error));
}

// A person photographs a ceiling light the way they would a painting high on a wall: from far
// enough back that the phone tilts up moderately, the light in the upper half of the frame and
// the room below it.
TEST(Simulator, PhotosOfCeilingLightsLookUpModeratelyWithTheLightHighInTheFrame) {
  Simulator simulator(FastOptions());
  QueryOptions options;
  options.width = 640;
  options.height = 480;
  const int count = 2 * static_cast<int>(simulator.scene().appliances.size());
  int overhead = 0;
  for (const QueryPhoto& photo : simulator.MakeQueries(count, options)) {
    const Appliance& target =
        simulator.scene().appliances[static_cast<size_t>(photo.target_appliance - 1)];
    if (target.points.front().z() <= options.overhead_min_height_m) continue;
    ++overhead;
    const Eigen::Vector3d to = target.points.front() - photo.world_from_cam.translation();
    const double elevation_deg = RadToDeg(std::atan2(to.z(), to.head<2>().norm()));
    EXPECT_LE(elevation_deg, options.overhead_max_elevation_deg + 1e-9) << target.name;
    // The optical axis (camera z) tilts up by at most elevation - offset + jitter.
    const Eigen::Vector3d axis = photo.world_from_cam.linear().col(2);
    const double pitch_deg = RadToDeg(std::asin(axis.z()));
    EXPECT_LE(pitch_deg, options.overhead_max_elevation_deg - options.overhead_frame_offset_deg +
                             options.max_pitch_jitter_deg + 1e-6)
        << target.name;
    const Eigen::Vector3d in_cam = photo.world_from_cam.inverse() * target.points.front();
    ASSERT_GT(in_cam.z(), 0.0) << target.name;
    EXPECT_LT(photo.intrinsics.Project(in_cam).y(), photo.intrinsics.cy) << target.name;
  }
  // The office's six ceiling lights and its ceiling-mounted projector, twice each.
  EXPECT_EQ(overhead, 14);
}

TEST(SimSource, OpensThroughOpenSourceWithOptions) {
  RegisterSimSource();
  auto source = capture::OpenSource("sim:office?trajectory=robot&session=2&seed=3&frames=3&fps=1");
  EXPECT_EQ(source->metadata().kind, "sim");
  EXPECT_TRUE(source->metadata().has_ground_truth);
  EXPECT_EQ(source->metadata().intrinsics.fx, 525.0);
  int frames = 0;
  while (auto frame = source->Next()) {
    EXPECT_TRUE(frame->world_from_cam_gt.has_value());
    EXPECT_NEAR(frame->world_from_cam_gt->translation().z(), 0.75, 1e-9);
    EXPECT_EQ(frame->timestamp_ns, frames * 1'000'000'000LL);
    EXPECT_EQ(frame->color.type(), CV_8UC3);
    EXPECT_EQ(frame->depth.type(), CV_16U);
    ++frames;
  }
  EXPECT_EQ(frames, 3);
  EXPECT_EQ(source->stats().paired_frames, 3);
  EXPECT_THROW(ParseSimLocation("office?colour=red"), InvalidArgument);
  EXPECT_THROW(ParseSimLocation("office?frames=many"), InvalidArgument);
  EXPECT_THROW(ParseSimLocation("office?trajectory=drone"), InvalidArgument);
  EXPECT_EQ(ParseSimLocation("office").frames, -1);
  EXPECT_THROW(capture::OpenSource("sim:/no/such/scene.json"), Error);
}

}  // namespace
}  // namespace sightmap::sim
