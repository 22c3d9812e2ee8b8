// What the mapper tells render/ about the map: plain data, no GL, no dependency on slam/ or store/.
//
// Keyframe points stay in their CAMERA frame and are drawn with the keyframe's world_from_cam as
// model matrix, so a pose corrected by loop closure moves the keyframe's points without uploading
// them again; adding a keyframe uploads only its own points.
//
// The world frame is the mapper's. Which axis is up is given once (MapScene's world_up): the
// synthetic building and a gravity-aligned map have z up (the default); a map anchored at the
// first camera frame (x right, y down, z forward) has up = -y of that camera, (0, -1, 0).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/tracking_state.h"

namespace sightmap::render {

struct MapKeyframe {
  int64_t id = 0;
  int session = 1;  // >= 1: trajectories are coloured by session
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3f> points_cam;     // camera frame [m], voxel-downsampled
  std::vector<std::array<uint8_t, 3>> colors;  // RGB, one per point
};

struct KeyframeCloudOptions {
  double voxel_m = 0.05;     // edge of the voxels that average points and colours [m]
  double min_depth_m = 0.3;  // depth outside [min, max] is dropped [m]
  double max_depth_m = 4.0;  // (far Kinect depth is noisy and blurs the floor plan)
  int pixel_step = 1;        // use every n-th pixel in each direction (>= 1)

  bool Check(std::string* error) const;
};

// One keyframe's coloured points from a registered BGR + depth [mm] pair: unprojected with
// `intrinsics`, averaged per voxel of the camera frame. id, session and pose are left for the
// caller to set.
MapKeyframe FromRgbd(const cv::Mat& bgr, const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                     const KeyframeCloudOptions& options = KeyframeCloudOptions());

struct PoseUpdate {
  int64_t id = 0;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
};

struct LoopEdge {
  int64_t from_id = 0;
  int64_t to_id = 0;

  bool operator==(const LoopEdge& other) const {
    return from_id == other.from_id && to_id == other.to_id;
  }
};

struct ApplianceLabel {
  std::string name;
  Eigen::Vector3d world_point = Eigen::Vector3d::Zero();  // [m]
};

// A keyframe that saw an appliance: one of its points in the keyframe's image and not hidden
// behind the keyframe's depth. The floor plan shows around each appliance the directions the
// keyframes that saw it stood in, so that the person mapping walks to the ones missing.
struct LabelSighting {
  int64_t keyframe_id = 0;
  int appliance = 0;  // index into the scene's appliances
};

// Directions around an appliance in the floor plane: `sectors` equal sectors, bearing 0 along the
// floor's first axis (core's FloorAxes of the scene's world_up), counted towards its second. A
// sighting counts for the sector its keyframe stands in when min_distance_m to max_distance_m from
// the appliance (as identify::CoverageOptions counts them) [m].
struct SectorOptions {
  int sectors = 12;
  double min_distance_m = 1.0;
  double max_distance_m = 4.0;

  bool Check(std::string* error) const;
};

struct MapStatus {
  int64_t keyframes = 0;
  int64_t loops = 0;
  TrackingState tracking = TrackingState::kTracking;
  double keyframes_per_s = 0.0;
  double elapsed_s = 0.0;
};

// A batch of changes. Several batches merge into one (MapMailbox coalesces while the renderer is
// busy): applying the merged batch equals applying them in order.
struct MapUpdate {
  std::vector<MapKeyframe> keyframes;  // new keyframes; a known id replaces that keyframe
  std::vector<PoseUpdate> poses;       // corrected poses of known keyframes (unknown ids ignored)
  std::vector<LoopEdge> loops;         // new loop-closure edges
  // Loop edges switched off (a loop the optimiser no longer trusts), each removing one edge of
  // those with its ends; applied before `loops`, so a loop switched off and later back on in
  // one merged batch is drawn.
  std::vector<LoopEdge> removed_loops;
  std::optional<Eigen::Isometry3d> camera;                // the current camera pose
  std::optional<std::vector<ApplianceLabel>> appliances;  // replaces every label
  std::vector<LabelSighting> sightings;                   // new sightings
  std::optional<MapStatus> status;

  void Merge(MapUpdate&& later);
  bool empty() const;
};

// The whole map as the renderer sees it (one per render thread).
class MapScene {
 public:
  explicit MapScene(const Eigen::Vector3d& world_up = Eigen::Vector3d::UnitZ());

  void Apply(MapUpdate&& update);

  const Eigen::Vector3d& world_up() const { return world_up_; }
  const std::map<int64_t, MapKeyframe>& keyframes() const { return keyframes_; }
  // Changes whenever keyframe `id`'s points change (added or replaced); 0 = unknown id.
  uint64_t points_version(int64_t id) const;
  const std::vector<LoopEdge>& loops() const { return loops_; }
  const std::optional<Eigen::Isometry3d>& camera() const { return camera_; }
  const std::vector<ApplianceLabel>& appliances() const { return appliances_; }
  const std::vector<LabelSighting>& sightings() const { return sightings_; }
  // Per appliance, a bit per sector seen by a sighting keyframe at its current pose (a loop
  // closure that moves a keyframe moves its sighting too).
  std::vector<uint64_t> SeenSectors(const SectorOptions& options) const;
  // The world direction in the floor plane at `bearing_deg` (see SectorOptions).
  Eigen::Vector3d FloorDirection(double bearing_deg) const;
  // The mapper's status; until it sends one, counts come from the scene.
  MapStatus status() const;
  size_t num_points() const { return num_points_; }

  // World points spread over the map (up to `per_keyframe` points of each keyframe, its camera
  // centre, the current camera and the appliances), for fitting views to the map's extent.
  std::vector<Eigen::Vector3d> ExtentSample(size_t per_keyframe = 64) const;

 private:
  Eigen::Vector3d world_up_;
  std::map<int64_t, MapKeyframe> keyframes_;
  std::map<int64_t, uint64_t> points_versions_;
  uint64_t next_version_ = 1;
  std::vector<LoopEdge> loops_;
  std::vector<LabelSighting> sightings_;
  Eigen::Vector3d floor_x_;  // the floor's axes (world_up_ x floor_x_ = floor_y_)
  Eigen::Vector3d floor_y_;
  std::optional<Eigen::Isometry3d> camera_;
  std::vector<ApplianceLabel> appliances_;
  std::optional<MapStatus> status_;
  size_t num_points_ = 0;
};

// Colour of session `session`'s trajectory, RGB in [0, 1] (a fixed palette, repeating).
Eigen::Vector3f SessionColor(int session);

}  // namespace sightmap::render
