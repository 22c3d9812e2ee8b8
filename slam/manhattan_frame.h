// The building's axes seen from one depth image. Offices are built square: floor, ceiling and most
// walls, desks and shelves lie in three orthogonal directions (a "Manhattan world"). A depth image
// that shows two of them fixes the camera's rotation relative to those axes, up to the 24 ways of
// naming them, and that measurement does not drift: a keyframe placed after seconds without
// registration (a blind turn at 1 Hz) gets back its heading from the walls it sees. This is the
// drift-free rotation of Kim, Coltin and Kim, "Low-drift visual odometry in structured
// environments by decoupling rotational and translational motion" (ICRA 2018), reduced to what
// the pose graph needs: one absolute rotation measurement per keyframe.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"

namespace sightmap::slam {

struct ManhattanOptions {
  // Normals are computed on the depth image sampled every `grid_step_px` pixels [px], each from
  // the points `normal_span_cells` cells to either side: a span of 2 x 4 x 6 = 48 px at the
  // default. Disparity quantisation makes a slanted plane a staircase, and a finite difference
  // over a short span takes one of a few slopes (histograms of 24 px normals on the simulated
  // walk peak 10-12 degrees either side of a wall's true direction); over 48 px the fitted
  // axes err 0.28 degrees at the median, 0.73 at p90 (1 Hz hand-held walk, seed 23).
  int grid_step_px = 4;
  int normal_span_cells = 6;
  // Points farther than this are not used [m]: depth noise grows with z^2 and a plane's normal
  // from far points is bent by it.
  double max_depth_m = 4.0;
  // A normal whose neighbours are not on one plane (an edge, a chair) is dropped: the two
  // tangents' points must lie within this of the plane through their centre [m per m of span].
  double max_planarity_error = 0.03;
  // A patch seen more obliquely than this is not used [deg, between its normal and the ray]:
  // edge-on, a plane's disparity steps are long and its normals lean towards the ray (a wall
  // seen along a window front bent one fit by 21 degrees).
  double max_incidence_deg = 75.0;
  // A normal belongs to an axis when within this angle of it [deg], while finding and while
  // refining the axes.
  double assign_deg = 10.0;
  // The camera is held upright: the building's vertical lies within this angle of the image's
  // vertical axis [deg] (a walker's camera turns its down axis at most 31 degrees between two
  // keyframes on the simulated hand-held walk, 14 over the real lounge frames).
  double max_tilt_deg = 40.0;
  // An axis counts when at least this many normals belong to it (each errs by about 4 degrees
  // on the simulated sensor, so their mean by a third of one); the rotation is measured when two
  // axes count. A count, not a share: a wall filling the view must not hide the floor below it.
  int min_axis_normals = 300;
  // Histogram bin of the walls' headings [deg].
  double heading_bin_deg = 1.0;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const ManhattanOptions& options);
void from_json(const nlohmann::json& json, ManhattanOptions& options);

struct ManhattanFit {
  // The building's axes in the camera frame (columns x, y, z; z the vertical). Any of the 24
  // rotations that permute and flip these columns fits as well (ManhattanSymmetries()).
  Eigen::Matrix3d cam_from_manhattan = Eigen::Matrix3d::Identity();
  std::array<int, 3> support{};  // normals assigned to each axis
  int normals = 0;               // valid normals
};

// A small plane patch a depth image shows: its unit normal (facing the camera) and its centre
// point, in the camera frame.
struct PlanePatch {
  Eigen::Vector3d normal;
  Eigen::Vector3d point;
};

// The depth image's plane patches on a grid of `grid_step_px`, each fitted over
// `normal_span_cells` cells to either side, within `max_depth_m`, not at an edge or a corner
// (`max_planarity_error`) nor seen edge-on (`max_incidence_deg`). Depth as FitManhattanFrame's
// (throws otherwise).
std::vector<PlanePatch> PlanePatches(const cv::Mat& depth_mm, const Intrinsics& camera,
                                     const ManhattanOptions& options);

// The camera's rotation relative to the building's axes, or nullopt when the image does not show
// two of them. The vertical is sought within max_tilt_deg of the image's up (-y): a walker holds
// the camera upright. `depth_mm` is 16-bit millimetres, 0 for no depth, of the size in `camera`.
std::optional<ManhattanFit> FitManhattanFrame(const cv::Mat& depth_mm, const Intrinsics& camera,
                                              const ManhattanOptions& options);
// The same from the image's plane patches (PlanePatches with the same options), for a caller
// that uses them for more than the axes.
std::optional<ManhattanFit> FitManhattanFrame(const std::vector<PlanePatch>& patches,
                                              const ManhattanOptions& options);

// The 24 proper rotations that map the coordinate axes onto themselves (with signs).
const std::vector<Eigen::Matrix3d>& ManhattanSymmetries();

// Of the rotations world_from_manhattan * S * cam_from_manhattan^T over the symmetries S, the one
// nearest `world_from_cam_estimate`, and its angle from it [rad].
std::pair<Eigen::Matrix3d, double> NearestManhattanRotation(
    const Eigen::Matrix3d& world_from_manhattan, const Eigen::Matrix3d& cam_from_manhattan,
    const Eigen::Matrix3d& world_from_cam_estimate);

}  // namespace sightmap::slam
