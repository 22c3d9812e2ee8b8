// Walls that hold apart parts of the map together. At 1 Hz a blind second leaves the map in rigid
// parts joined only by motion priors, each part's heading held by the building's axes but its
// position off by the prior's error (robot walk, seed 23: 74 parts 0.03-0.31 m apart). Two parts
// that see the same wall agree on where it is along its normal: the plane's offset, measured in
// each keyframe's depth, ties the parts' positions along that normal whatever their views share.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>

#include "slam/manhattan_frame.h"
#include "slam/pose_graph.h"

namespace sightmap::slam {

// A plane of the building's axes in one keyframe's depth: the points x (camera frame) with
// normal_cam . x = offset_m (negative: the normal faces the camera).
struct AxisPlane {
  Eigen::Vector3d normal_cam = Eigen::Vector3d::UnitZ();
  double offset_m = 0.0;
  int support = 0;  // plane patches on it
  Eigen::Vector3d centroid_cam = Eigen::Vector3d::Zero();
};

struct WallTieOptions {
  // Plane patches within this angle of an axis belong to it [deg].
  double assign_deg = 8.0;
  // Offsets are histogrammed in bins of this width [m]; a plane is a peak of at least
  // `min_support` patches within `peak_halfwidth_m` of it, at least `min_separation_m` from a
  // stronger one.
  double bin_m = 0.02;
  double peak_halfwidth_m = 0.04;
  int min_support = 400;
  double min_separation_m = 0.15;
  // A plane's patches must span this both ways [m], between their 2nd and 98th percentiles: not a
  // door jamb's face, which stands 0.36 m before two of the office's walls and was tied to them
  // (1 Hz hand-held seed 7: 0.162 m with any extent, 0.104 m from 0.3 m; 0.5 m and more lose
  // walls seen in part, seed 5 0.048 -> 0.055 m at 0.5, 0.139 m at 0.75).
  double min_extent_m = 0.3;
  // Tying: two keyframes' planes on the same axis and side, their offsets in the world within
  // `max_offset_gap_m` and their centroids within `max_centroid_distance_m`, neither keyframe
  // holding another plane of that side within `min_unique_gap_m` of the other's offset.
  double max_offset_gap_m = 0.2;
  double max_centroid_distance_m = 3.0;
  double min_unique_gap_m = 0.4;
  // A plane's world normal must lie within this of an axis [deg].
  double snap_deg = 5.0;
  // Two parts are tied on a wall only when at least `min_agreeing` of their keyframe pairs seeing
  // it, and more than half, agree on the offset between them within `agree_m` [m].
  double agree_m = 0.05;
  int min_agreeing = 2;
  // At most this many ties between two parts on one wall (the best supported).
  int max_ties_per_wall = 3;
  double sigma_m = 0.03;  // of a tie's offset difference

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const WallTieOptions& options);
void from_json(const nlohmann::json& json, WallTieOptions& options);

// The planes of the building's axes (cam_from_axes: FitManhattanFrame's) among a depth image's
// plane patches (PlanePatches).
std::vector<AxisPlane> FindAxisPlanes(const std::vector<PlanePatch>& patches,
                                      const Eigen::Matrix3d& cam_from_axes,
                                      const WallTieOptions& options);

// A keyframe's planes and where the map has it; `part` names its rigid part (keyframes joined by
// registrations), as ties are made only between parts.
struct PlaneSightings {
  int64_t id = 0;
  int part = 0;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  std::vector<AxisPlane> planes;
};

// Ties between keyframes of different parts seeing the same plane (world_from_axes: where the
// building's axes lie in the map).
std::vector<PlaneTie> TieWalls(const std::vector<PlaneSightings>& keyframes,
                               const Eigen::Matrix3d& world_from_axes,
                               const WallTieOptions& options);

}  // namespace sightmap::slam
