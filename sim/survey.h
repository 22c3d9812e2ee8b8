// The survey walk (trajectory=survey): the capture a building manager makes who follows the
// coverage guidance (`sightmap coverage`): every appliance seen from several standpoints spread
// over its front, 1-4 m away, walking along the walls of each room and through its middle.
//
// The plan is built in stages, each tested on its own:
//   FloorGrid          the floor a person can stand on (free of boxes at foot, hip and head
//                      height, inside a room), with shortest paths between two points;
//   ChooseStandpoints  per appliance, its open front (the bearings from which a standpoint in its
//                      room has a clear line of sight) and standpoints spread over it;
//   OrderStops         in the order the scene's tour passes them, with each room's middle walked
//                      through after its last standpoint;
//   PlanSurvey         the stops joined by shortest paths into one closed walk.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "sim/scene.h"

namespace sightmap::sim {

struct SurveyOptions {
  int standpoints_per_appliance = 3;  // >= 1
  // Standpoints at the appliance's front and this far to either side of it [deg] (narrower when
  // its open arc is: the wall a thermostat hangs on leaves about 170 deg).
  double spread_deg = 60.0;
  double distance_m = 2.0;  // preferred horizontal distance to the appliance [m]
  // Appliances higher than overhead_min_height_m (ceiling lights, projectors) are looked at from
  // further away, so the camera tilts up no more than a person comfortably does.
  double overhead_distance_m = 2.5;    // [m]
  double overhead_min_height_m = 2.2;  // [m]
  // No standpoint sees its appliance more steeply than this from eye height [deg]: people look
  // up at a light from a few steps away, not from under it.
  double max_elevation_deg = 30.0;
  double min_distance_m = 1.0;  // standpoints within [min, max] of the appliance [m]
  double max_distance_m = 4.0;
  double eye_height_m = 1.55;  // for the lines of sight [m]
  double clearance_m = 0.3;    // free floor around the walker's centre [m]
  double grid_m = 0.1;         // floor grid cell [m]

  bool Check(std::string* error) const;
};

// Floor cells a walker of the given clearance can stand on: inside a room and at least the
// clearance (horizontally) from every box that reaches between 0.05 and 1.9 m above the floor.
class FloorGrid {
 public:
  FloorGrid(const Scene& scene, double cell_m, double clearance_m);

  bool IsFree(const Eigen::Vector2d& p) const;
  // The free cell centre nearest to p (within 2 m), or nullopt.
  std::optional<Eigen::Vector2d> NearestFree(const Eigen::Vector2d& p) const;
  // The shortest walk from a to b over free cells (8-connected A*, then shortened by straight
  // lines of sight over free cells); starts at a and ends at b. Throws sightmap::Error when b
  // cannot be reached from a.
  std::vector<Eigen::Vector2d> ShortestPath(const Eigen::Vector2d& a,
                                            const Eigen::Vector2d& b) const;
  // True when the straight segment from a to b crosses free cells only.
  bool StraightIsFree(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  int width() const { return width_; }
  int height() const { return height_; }

 private:
  int Index(int x, int y) const { return y * width_ + x; }
  Eigen::Vector2i CellOf(const Eigen::Vector2d& p) const;
  Eigen::Vector2d CentreOf(int x, int y) const;

  double cell_m_ = 0.1;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();  // corner of cell (0, 0) [m]
  int width_ = 0;
  int height_ = 0;
  std::vector<unsigned char> free_;
};

struct SurveyStop {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // where the walker stands [m]
  // The appliance point looked at while standing here; nullopt for a room's middle, which is
  // walked through without stopping.
  std::optional<Eigen::Vector3d> target;
  int appliance_id = 0;  // 0 for a room's middle
  std::string room;
  double bearing_deg = 0.0;  // of the standpoint seen from the appliance, from +x [deg]
  double arc_m = 0.0;        // where the stop lies along the plan's path [m]
};

// Where one appliance can be surveyed from.
struct Standpoints {
  double front_deg = 0.0;     // middle of the widest open arc, bearing from the appliance [deg]
  double open_arc_deg = 0.0;  // width of that arc (360: open all around) [deg]
  std::vector<SurveyStop> stops;
};

// The standpoints for one appliance: `standpoints_per_appliance` bearings centred on its front
// and spread_deg apart, 25 deg clear of the open arc's ends (closer together when the open arc is
// narrower; fewer when it is too
// narrow for distinct standpoints 0.3 m apart), each at the distance along its bearing with the
// richest view (ViewScore, less 2 per metre from the preferred distance). A standpoint is free
// floor in the appliance's room with a clear line of sight from eye height and nothing within
// 0.8 m 12 deg to either side of it (no view grazing a wall; dropped when no standpoint has such a
// view). Throws sightmap::Error naming the appliance when no standpoint exists.
Standpoints ChooseStandpoints(const Scene& scene, const FloorGrid& grid, const Appliance& appliance,
                              const SurveyOptions& options);

// The stops room by room, rooms in the order the scene's tour first comes near them; within a
// room around it (by bearing from its centre, from the stop and in the direction that make the
// walk from the previous room to this one's middle shortest), then through its middle (a stop
// without target at the nearest free cell to the centre).
std::vector<SurveyStop> OrderStops(const Scene& scene, const FloorGrid& grid,
                                   std::vector<SurveyStop> stops);

struct SurveyPlan {
  std::vector<Eigen::Vector2d> path;  // closed: the last point is the first [m]
  std::vector<SurveyStop> stops;      // in walking order, arc_m set; stops[0] at arc 0
  double length_m = 0.0;              // of one lap
};

// The whole survey of the scene: every appliance's standpoints joined by shortest paths, a lap
// that returns to its first stop. Throws sightmap::Error naming an appliance that cannot be
// surveyed.
SurveyPlan PlanSurvey(const Scene& scene, const SurveyOptions& options = SurveyOptions());

}  // namespace sightmap::sim
