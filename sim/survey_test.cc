#include "sim/survey.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rotation.h"
#include "sim/simulator.h"
#include "sim/trajectory.h"

namespace sightmap::sim {
namespace {

SceneBox Box(const std::string& name, const Eigen::Vector3d& center, const Eigen::Vector3d& size) {
  SceneBox box;
  box.name = name;
  box.center = center;
  box.size = size;
  box.material = "wall";
  return box;
}

Appliance MakeAppliance(int id, const std::string& name, const Eigen::Vector3d& point,
                        const SceneBox& box) {
  Appliance appliance;
  appliance.id = id;
  appliance.name = name;
  appliance.type = name;
  appliance.points = {point};
  appliance.boxes = {box};
  return appliance;
}

// Two 6 x 6 m / 5 x 6 m rooms joined by a 1 m door at y = 2.5-3.5 in the wall x = 6; a table in
// the middle of room a with a ceiling light over it; a thermostat on the far wall of room b; a
// closed room c behind that wall.
Scene TwoRooms() {
  Scene scene;
  scene.name = "two_rooms";
  scene.rooms = {{"a", {0, 0}, {6, 6}}, {"b", {6, 0}, {11, 6}}, {"c", {11, 0}, {13, 6}}};
  scene.boxes.push_back(Box("wall_door_south", {6, 1.25, 1.4}, {0.12, 2.5, 2.8}));
  scene.boxes.push_back(Box("wall_door_north", {6, 4.75, 1.4}, {0.12, 2.5, 2.8}));
  scene.boxes.push_back(Box("wall_far", {11.06, 3, 1.4}, {0.12, 6, 2.8}));
  scene.boxes.push_back(Box("table", {3, 3, 0.37}, {1.2, 0.8, 0.74}));
  scene.boxes.push_back(Box("floor", {6, 3, -0.05}, {14, 8, 0.1}));  // walked on, not around
  scene.appliances = {
      MakeAppliance(1, "thermostat", {10.97, 3, 1.5},
                    Box("thermostat", {10.98, 3, 1.5}, {0.04, 0.1, 0.1})),
      MakeAppliance(2, "light", {3, 3, 2.77}, Box("light", {3, 3, 2.78}, {0.6, 0.6, 0.04}))};
  scene.tour = {{1, 1}, {5, 1}, {7, 3}, {10, 1}, {10, 5}, {7, 5}, {5, 5}, {1, 5}};
  return scene;
}

double PathLength(const std::vector<Eigen::Vector2d>& path) {
  double length = 0.0;
  for (size_t i = 1; i < path.size(); ++i) length += (path[i] - path[i - 1]).norm();
  return length;
}

bool ClearLineOfSight(const Scene& scene, const SurveyStop& stop, double eye_height_m) {
  const Eigen::Vector3d eye(stop.position.x(), stop.position.y(), eye_height_m);
  const Eigen::Vector3d ray = *stop.target - eye;
  return !scene.Raycast(eye, ray.normalized(), ray.norm() - 0.05, stop.appliance_id).has_value();
}

TEST(FloorGrid, WallsFurnitureAndDoorsShapeTheWalkableFloor) {
  const Scene scene = TwoRooms();
  const FloorGrid grid(scene, 0.1, 0.3);
  EXPECT_TRUE(grid.IsFree({1, 1}));
  EXPECT_TRUE(grid.IsFree({6, 3}));      // the door
  EXPECT_FALSE(grid.IsFree({6, 1}));     // the wall beside it
  EXPECT_FALSE(grid.IsFree({6, 2.65}));  // too close to the door jamb for a walker
  EXPECT_FALSE(grid.IsFree({3, 3}));     // under the table
  EXPECT_FALSE(grid.IsFree({3.85, 3}));  // beside it, within the clearance
  EXPECT_TRUE(grid.IsFree({4.05, 3}));   // beyond the clearance
  EXPECT_FALSE(grid.IsFree({14, 2}));    // outside every room
  EXPECT_FALSE(grid.IsFree({-0.05, 2}));

  const std::vector<Eigen::Vector2d> path = grid.ShortestPath({1, 3}, {10, 3});
  ASSERT_GE(path.size(), 3u);
  EXPECT_EQ(path.front(), Eigen::Vector2d(1, 3));
  EXPECT_EQ(path.back(), Eigen::Vector2d(10, 3));
  for (size_t i = 1; i < path.size(); ++i) EXPECT_TRUE(grid.StraightIsFree(path[i - 1], path[i]));
  // Around the table (0.7 m off the straight line with the clearance) and back to the door: a
  // little longer than the straight 9 m, far shorter than a detour along the walls.
  const double length = PathLength(path);
  EXPECT_GT(length, 9.1);
  EXPECT_LT(length, 9.6);
  bool through_door = false;
  for (size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d& a = path[i - 1];
    const Eigen::Vector2d& b = path[i];
    if ((a.x() - 6) * (b.x() - 6) <= 0 && a.x() != b.x()) {
      const double y = a.y() + (b.y() - a.y()) * (6 - a.x()) / (b.x() - a.x());
      through_door = std::abs(y - 3) < 0.25;
    }
  }
  EXPECT_TRUE(through_door);

  EXPECT_THROW(grid.ShortestPath({1, 3}, {12, 3}), Error);  // room c has no door
  EXPECT_THROW(grid.ShortestPath({1, 3}, {3, 3}), Error);   // under the table
  // Nearest to the table's middle: out of its long side, 0.4 + 0.3 m away (cell centres).
  EXPECT_NEAR((grid.NearestFree({3, 3}).value() - Eigen::Vector2d(3, 3)).norm(), 0.75, 0.01);
}

TEST(Survey, AWallApplianceIsSeenFromThreeStandpointsSpreadOverItsFront) {
  const Scene scene = TwoRooms();
  SurveyOptions options;
  const FloorGrid grid(scene, options.grid_m, options.clearance_m);
  const Standpoints standpoints = ChooseStandpoints(scene, grid, scene.appliances[0], options);
  EXPECT_NEAR(std::abs(standpoints.front_deg), 180.0, 5.1);
  EXPECT_NEAR(standpoints.open_arc_deg, 180.0, 30.0);  // the wall's side, less grazing views
  const std::vector<SurveyStop>& stops = standpoints.stops;
  ASSERT_EQ(stops.size(), 3u);
  std::vector<double> bearings;
  for (const SurveyStop& stop : stops) {
    EXPECT_EQ(stop.appliance_id, 1);
    EXPECT_EQ(stop.room, "b");
    ASSERT_TRUE(stop.target.has_value());
    const double distance = (stop.position - stop.target->head<2>()).norm();
    EXPECT_NEAR(distance, options.distance_m, 0.26);
    EXPECT_TRUE(grid.IsFree(stop.position));
    EXPECT_TRUE(ClearLineOfSight(scene, stop, options.eye_height_m));
    bearings.push_back(stop.bearing_deg < 0 ? stop.bearing_deg + 360 : stop.bearing_deg);
  }
  // The wall faces -x: the front is 180 deg, the standpoints at 120, 180 and 240 deg.
  EXPECT_NEAR(bearings[0], 120.0, 5.1);
  EXPECT_NEAR(bearings[1], 180.0, 5.1);
  EXPECT_NEAR(bearings[2], 240.0, 5.1);
}

TEST(Survey, ACeilingLightIsLookedAtFromFurtherAwaySoTheCameraTiltsModerately) {
  const Scene scene = TwoRooms();
  SurveyOptions options;
  options.standpoints_per_appliance = 4;
  const FloorGrid grid(scene, options.grid_m, options.clearance_m);
  const Standpoints standpoints = ChooseStandpoints(scene, grid, scene.appliances[1], options);
  EXPECT_EQ(standpoints.open_arc_deg, 360.0);
  const std::vector<SurveyStop>& stops = standpoints.stops;
  ASSERT_EQ(stops.size(), 4u);
  std::set<long> distinct;
  for (const SurveyStop& stop : stops) {
    const double distance = (stop.position - stop.target->head<2>()).norm();
    EXPECT_NEAR(distance, options.overhead_distance_m, 0.26);
    const double elevation_deg =
        RadToDeg(std::atan2(stop.target->z() - options.eye_height_m, distance));
    EXPECT_LE(elevation_deg, options.max_elevation_deg);
    EXPECT_EQ(stop.room, "a");
    EXPECT_TRUE(ClearLineOfSight(scene, stop, options.eye_height_m));
    distinct.insert(std::lround(stop.bearing_deg));
  }
  EXPECT_EQ(distinct.size(), 4u);
  // Wanting them closer than the elevation limit allows keeps them at the limit's distance.
  options.overhead_distance_m = 1.0;
  for (const SurveyStop& stop :
       ChooseStandpoints(scene, grid, scene.appliances[1], options).stops) {
    const double distance = (stop.position - stop.target->head<2>()).norm();
    EXPECT_GE(distance, (2.77 - options.eye_height_m) / std::tan(DegToRad(30.0)));
  }
}

TEST(Survey, AnApplianceNobodyCanSeeIsNamed) {
  Scene scene = TwoRooms();
  // Boxed in on every side.
  scene.boxes.push_back(Box("cupboard", {10.6, 3, 1.0}, {0.6, 1.0, 2.0}));
  const FloorGrid grid(scene, 0.1, 0.3);
  try {
    ChooseStandpoints(scene, grid, scene.appliances[0], SurveyOptions());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("thermostat"), std::string::npos) << e.what();
  }
}

TEST(Survey, StopsGoRoomByRoomAroundEachRoomAndThroughItsMiddle) {
  const Scene scene = TwoRooms();
  SurveyOptions options;
  const FloorGrid grid(scene, options.grid_m, options.clearance_m);
  std::vector<SurveyStop> stops =
      ChooseStandpoints(scene, grid, scene.appliances[0], options).stops;
  for (const SurveyStop& stop :
       ChooseStandpoints(scene, grid, scene.appliances[1], options).stops) {
    stops.push_back(stop);
  }
  const std::vector<SurveyStop> ordered = OrderStops(scene, grid, stops);
  // The tour starts in room a: the light's 3 standpoints, a's middle, the thermostat's 3, b's.
  ASSERT_EQ(ordered.size(), 8u);
  const std::vector<int> ids = {2, 2, 2, 0, 1, 1, 1, 0};
  for (size_t i = 0; i < ordered.size(); ++i) {
    EXPECT_EQ(ordered[i].appliance_id, ids[i]) << i;
    EXPECT_EQ(ordered[i].target.has_value(), ids[i] != 0) << i;
  }
  EXPECT_EQ(ordered[3].room, "a");
  EXPECT_EQ(ordered[7].room, "b");
  // a's middle is under the table: the nearest free floor beside it.
  EXPECT_NEAR((ordered[3].position - Eigen::Vector2d(3, 3)).norm(), 0.75, 0.01);
  EXPECT_NEAR((ordered[7].position - Eigen::Vector2d(8.5, 3)).norm(), 0.0, 1e-9);
}

// The embedded office: every appliance gets its standpoints, the lap is one closed walk over
// free floor, and standpoints are where the issue wants them (1-4 m, spread over the front).
TEST(Survey, TheOfficeSurveyCoversEveryApplianceInOneClosedWalk) {
  const Scene scene = LoadScene("office");
  const SurveyOptions options;
  const SurveyPlan plan = PlanSurvey(scene, options);
  const FloorGrid grid(scene, options.grid_m, options.clearance_m);
  std::map<int, std::vector<SurveyStop>> by_appliance;
  int middles = 0;
  for (const SurveyStop& stop : plan.stops) {
    if (stop.appliance_id == 0) {
      ++middles;
      continue;
    }
    by_appliance[stop.appliance_id].push_back(stop);
  }
  EXPECT_EQ(by_appliance.size(), scene.appliances.size());
  EXPECT_GE(middles, static_cast<int>(scene.rooms.size()));
  // Three standpoints over at least 60 deg wherever the appliance's open arc allows; the office
  // has one appliance that does not: switch_c, on the hinge side of an open door whose leaf hides
  // it from everywhere but along its wall (a scene quirk kept: photos are drawn in this scene).
  int narrow = 0;
  int wide = 0;  // appliances whose standpoints spread over 60 deg or more
  for (const Appliance& appliance : scene.appliances) {
    const std::vector<SurveyStop>& stops = by_appliance[appliance.id];
    const Standpoints chosen = ChooseStandpoints(scene, grid, appliance, options);
    ASSERT_EQ(stops.size(), chosen.stops.size()) << appliance.name;
    ASSERT_GE(stops.size(), 1u) << appliance.name;
    if (chosen.open_arc_deg < 60.0) {
      ++narrow;
      EXPECT_EQ(appliance.name, "switch_c");
      continue;
    }
    ASSERT_EQ(stops.size(), 3u) << appliance.name;
    double min_bearing = 1e9, max_bearing = -1e9;
    for (const SurveyStop& stop : stops) {
      const double distance = (stop.position - stop.target->head<2>()).norm();
      EXPECT_GE(distance, options.min_distance_m - 1e-9);
      EXPECT_LE(distance, options.max_distance_m + 1e-9);
      EXPECT_TRUE(ClearLineOfSight(scene, stop, options.eye_height_m)) << appliance.name;
      // Relative to the middle standpoint, unwrapped.
      const double relative = std::remainder(stop.bearing_deg - stops[1].bearing_deg, 360.0);
      min_bearing = std::min(min_bearing, relative);
      max_bearing = std::max(max_bearing, relative);
    }
    // As wide as the arc less its 25 deg margins allows, up to 2 x 60 deg.
    const double usable = chosen.open_arc_deg < 360.0 ? chosen.open_arc_deg - 50.0 : 360.0;
    EXPECT_GE(max_bearing - min_bearing, std::min(120.0, usable) - 5.0) << appliance.name;
    wide += max_bearing - min_bearing >= 60.0;
  }
  EXPECT_LE(narrow, 1);
  // Measured: 17 of 21; the desk lamp, thermostat_a and monitor_3 stand in cramped corners
  // (open arcs of 65-85 deg), switch_c behind its door.
  EXPECT_GE(wide, 17);
  // Each room is surveyed in one visit, around it: its standpoints in the order of their bearing
  // from the room's centre (one way round, starting anywhere), then its middle.
  std::map<std::string, std::vector<Eigen::Vector2d>> runs;
  std::string previous_room;
  for (const SurveyStop& stop : plan.stops) {
    if (stop.room != previous_room) {
      EXPECT_EQ(runs.count(stop.room), 0u) << stop.room << " visited twice";
      previous_room = stop.room;
    }
    if (stop.target) runs[stop.room].push_back(stop.position);
  }
  EXPECT_EQ(runs.size(), scene.rooms.size());
  for (const auto& run : runs) {
    const std::string& name = run.first;  // a plain reference: the lambda below captures it
    const std::vector<Eigen::Vector2d>& positions = run.second;
    const auto room = std::find_if(scene.rooms.begin(), scene.rooms.end(),
                                   [&](const Room& r) { return r.name == name; });
    ASSERT_NE(room, scene.rooms.end());
    const Eigen::Vector2d centre = 0.5 * (room->min + room->max);
    std::vector<std::pair<double, size_t>> by_bearing;
    for (size_t i = 0; i < positions.size(); ++i) {
      const Eigen::Vector2d d = positions[i] - centre;
      by_bearing.emplace_back(std::atan2(d.y(), d.x()), i);
    }
    std::sort(by_bearing.begin(), by_bearing.end());
    std::vector<long> rank(positions.size());
    for (size_t r = 0; r < by_bearing.size(); ++r)
      rank[by_bearing[r].second] = static_cast<long>(r);
    const long n = static_cast<long>(positions.size());
    if (n < 3) continue;
    const long step = ((rank[1] - rank[0]) % n + n) % n;
    EXPECT_TRUE(step == 1 || step == n - 1) << name;
    for (long i = 1; i < n; ++i) {
      EXPECT_EQ(((rank[i] - rank[i - 1]) % n + n) % n, step) << name << " stop " << i;
    }
  }
  ASSERT_GE(plan.path.size(), 2u);
  EXPECT_LT((plan.path.front() - plan.path.back()).norm(), 1e-9);
  for (size_t i = 1; i < plan.path.size(); ++i) {
    EXPECT_TRUE(grid.StraightIsFree(plan.path[i - 1], plan.path[i])) << i;
  }
  EXPECT_NEAR(PathLength(plan.path), plan.length_m, 1e-6);
  for (size_t i = 1; i < plan.stops.size(); ++i) {
    EXPECT_GE(plan.stops[i].arc_m, plan.stops[i - 1].arc_m);
  }
}

// Walked: standing at a standpoint, the appliance is near the image centre; the walker never
// exceeds walking speed or the turn rate, stays on free floor and tilts up at most 35 deg.
TEST(Survey, TheSurveyWalkLooksAtEachApplianceFromEachStandpoint) {
  const Scene scene = LoadScene("office");
  TrajectoryOptions options;
  options.kind = TrajectoryKind::kSurvey;
  options.seed = 5;
  const Trajectory trajectory(scene, options);
  ASSERT_TRUE(trajectory.survey_plan().has_value());
  const SurveyPlan& plan = *trajectory.survey_plan();
  const Intrinsics camera = KinectIntrinsics();
  const double lap = trajectory.lap_duration_s();
  const double dt = 1.0 / 30.0;
  std::vector<Eigen::Isometry3d> poses;
  for (double t = 0.0; t < lap + 1.0; t += dt) poses.push_back(trajectory.WorldFromCam(t));
  double max_speed = 0.0, max_turn_dps = 0.0, max_tilt_dps = 0.0;
  int facing_a_surface = 0;  // frames whose optical axis meets a surface within 0.6 m
  for (size_t i = 1; i + 30 < poses.size(); ++i) {
    const Eigen::Isometry3d& pose = poses[i];
    const Eigen::Vector3d p = pose.translation();
    // Speed over 1 s, which averages out the sideways sway of the steps (period 1.1 s).
    max_speed = std::max(max_speed, (poses[i + 30].translation() - p).head<2>().norm());
    ASSERT_TRUE(scene.IsFree(p, 0.05)) << "t=" << i * dt << ": " << p.transpose();
    const double pitch = std::asin(pose.linear().col(2).z());
    ASSERT_LE(std::abs(pitch), DegToRad(35.0) + 1e-9) << i * dt;
    const Eigen::Vector3d f0 = poses[i - 1].linear().col(2), f1 = pose.linear().col(2);
    const double turn =
        std::atan2(f0.x() * f1.y() - f0.y() * f1.x(), f0.head<2>().dot(f1.head<2>()));
    max_turn_dps = std::max(max_turn_dps, RadToDeg(std::abs(turn) / dt));
    const double pitch_before = std::asin(f0.z());
    max_tilt_dps = std::max(max_tilt_dps, RadToDeg(std::abs(pitch - pitch_before) / dt));
    facing_a_surface += scene.Raycast(p, f1, 0.6).has_value();
  }
  // The walker keeps the view open (the sensor measures nothing within 0.5 m).
  EXPECT_LT(facing_a_surface, static_cast<int>(0.002 * poses.size())) << facing_a_surface;
  int standing = 0;
  for (const SurveyStop& stop : plan.stops) {
    if (!stop.target) continue;
    ++standing;
    // Some time the walker stands here (not moving over 0.5 s) with the appliance near the
    // image centre.
    bool centred = false;
    for (size_t i = 0; i + 15 < poses.size() && !centred; i += 15) {
      const Eigen::Isometry3d& pose = poses[i];
      if ((pose.translation().head<2>() - stop.position).norm() > 0.05 ||
          (poses[i + 15].translation() - pose.translation()).head<2>().norm() > 0.03) {
        continue;
      }
      const Eigen::Vector3d in_cam = pose.inverse() * *stop.target;
      if (in_cam.z() <= 0) continue;
      const Eigen::Vector2d pixel = camera.Project(in_cam);
      centred = std::abs(pixel.x() - camera.cx) < 0.3 * camera.width &&
                std::abs(pixel.y() - camera.cy) < 0.3 * camera.height;
    }
    EXPECT_TRUE(centred) << "standpoint (" << stop.position.transpose() << ") of appliance "
                         << stop.appliance_id;
  }
  // Three per appliance but switch_c (see above).
  EXPECT_EQ(standing, 3 * static_cast<int>(scene.appliances.size()) - 2);
  EXPECT_LE(max_speed, 0.3 * 1.05);
  EXPECT_LE(max_turn_dps, 35.0 * 1.1);
  // The camera tilts smoothly too: from a ceiling light to the next appliance over seconds, not
  // between two frames.
  EXPECT_LE(max_tilt_dps, 45.0);
  // One lap: standing 5 s at each standpoint, walking at 0.3 m/s, 0.6 s more per leg for
  // speeding up and slowing down, legs between close standpoints stretched to 2 s.
  EXPECT_GT(lap, standing * 5.0 + plan.length_m / 0.3);
  EXPECT_LE(lap, standing * 5.0 + plan.length_m / 0.3 + 2.0 * plan.stops.size());
}

}  // namespace
}  // namespace sightmap::sim
