// From which directions and distances the walk saw each labelled appliance, and which directions
// it missed: the guidance a manager needs to walk back to what is missing.
//
// Why: photos are taken from where people stand. On 200 session-2 photos against a 600-keyframe
// walk, 126 had no keyframe within 40 degrees of their viewing direction, and local features match
// only what the walk saw from a similar direction: coverage, not the matcher, capped the share of
// photos located.
//
// Around each label, the floor plane is cut into sectors (12 of 30 degrees by default). A sector is
// seen when a keyframe standing in it, min_distance_m to max_distance_m from the label, had one of
// the label's points in its image and not hidden behind its depth. A sector is open when a person
// could stand there and see the label: a standpoint at eye height in it (probed at a few
// distances) lies in space the keyframes' depth rays crossed, and so does the line of sight to
// the label, with no measured surface on it. Sectors behind the wall an appliance hangs on are
// never open; a seen sector is open whatever the probe says. Coverage is seen / open.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/ids.h"
#include "identify/labels.h"
#include "store/model.h"

namespace sightmap::identify {

struct CoverageOptions {
  // Sectors around each label in the floor plane.
  int sectors = 12;
  // Keyframes count for a sector within this distance band of the label: features of a view much
  // nearer or further than a photo's do not match it (ORB's pyramid spans 3.6x) [m].
  double min_distance_m = 1.0;
  double max_distance_m = 4.0;
  // Standpoints probed per sector, evenly spread over the distance band.
  int probes_per_sector = 3;
  // Free space: cells of this size [m] that a depth ray crossed (every free_space_pixel_step-th
  // pixel of each keyframe's depth, up to free_space_margin_m short of the surface it hit).
  // Cells with a measured surface block the line of sight.
  double cell_m = 0.2;
  int free_space_pixel_step = 16;
  double free_space_margin_m = 0.1;
  double max_depth_m = 8.0;  // depths beyond are not trusted (Kinect-class range) [m]
  // The line of sight is not checked this near the label: the appliance's own surface and the
  // wall it hangs on are there [m].
  double label_clearance_m = 0.4;
  // When a keyframe sees a label (in its image, not hidden).
  LabelViewOptions view;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const CoverageOptions& options);
void from_json(const nlohmann::json& json, CoverageOptions& options);

struct SectorCoverage {
  // Bearing range from the label in the floor plane [deg], measured from the floor's first axis
  // (the world x axis projected on the floor) towards its second (up x first).
  double from_deg = 0.0;
  double to_deg = 0.0;
  bool open = false;
  int keyframes = 0;        // keyframes in this sector and distance band that saw the label
  double nearest_m = 0.0;   // of those (0 when none)
  double farthest_m = 0.0;  // of those
  // The probed distances from which a person could stand and see the label, nearest first (none
  // in a sector only keyframes opened) [m].
  std::vector<double> open_distances_m;
  bool seen() const { return keyframes > 0; }
};

struct LabelCoverage {
  LabelId id;
  std::string name;
  std::string type;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // mean of its points [m]
  std::vector<SectorCoverage> sectors;
  int open = 0;
  int seen = 0;
  int keyframes = 0;  // keyframes that saw it at any distance
  double share() const { return open > 0 ? static_cast<double>(seen) / open : 0.0; }
};

// What the keyframes' depth showed within 0.6 m of eye height, seen from above: each floor cell
// holds the most telling state of the space above it (a measured surface over crossed space over
// nothing known).
struct FloorPlan {
  enum Cell : uint8_t { kUnknown = 0, kFree = 1, kSurface = 2 };
  cv::Mat cells;                                     // CV_8UC1; row = floor y, column = floor x
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // floor coordinates of cell (0, 0)'s corner
  double cell_m = 0.2;
  std::vector<Eigen::Vector2d> keyframes;  // where each keyframe stood (floor coordinates)
};

struct ModelCoverage {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // the world's up, estimated from the keyframes
  Eigen::Vector3d floor_x = Eigen::Vector3d::UnitX();  // the floor plane's axes (FloorAxes)
  Eigen::Vector3d floor_y = Eigen::Vector3d::UnitY();
  double eye_height_m = 0.0;          // the keyframes' mean height along up [m]
  std::vector<LabelCoverage> labels;  // by name
  FloorPlan floor;
  int open = 0;
  int seen = 0;
  double share() const { return open > 0 ? static_cast<double>(seen) / open : 0.0; }
};

// The world's up direction from keyframe orientations: the mean of their image-up axes (-y of the
// camera). A person or a robot holds the sensor roughly level, so the mean is the vertical to a
// few degrees; a map anchored at its first camera has no other clue to it.
Eigen::Vector3d EstimateWorldUp(const std::vector<store::KeyframeInfo>& keyframes);

// Coverage of every label of `model` by its keyframes (each keyframe's depth read once).
// `progress` (optional) is called with the keyframes done and the total.
ModelCoverage ComputeCoverage(const store::Model& model,
                              const CoverageOptions& options = CoverageOptions(),
                              const std::function<void(int, int)>& progress = nullptr);

// The "covered" photo: some keyframe saw the point the photo is taken of from a similar
// view: the point inside the keyframe's image and in front of it, the keyframe's line of sight to
// it within max_angle_deg of the photo's, and its distance to it within a factor
// max_distance_ratio of the photo's. (Occlusion is not checked: a keyframe behind a wall from
// the point could count; in practice its image shows the wall, so retrieval never picks it.)
struct ViewSeenOptions {
  double max_angle_deg = 40.0;
  double max_distance_ratio = 2.0;
  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const ViewSeenOptions& options);
void from_json(const nlohmann::json& json, ViewSeenOptions& options);
bool ViewWasSeen(const Eigen::Isometry3d& world_from_photo, const Eigen::Vector3d& point_world,
                 const std::vector<store::KeyframeInfo>& keyframes,
                 const ViewSeenOptions& options = ViewSeenOptions());
// The smallest angle between the photo's line of sight to the point and that of a keyframe with
// the point in its image, within a factor max_distance_ratio of the photo's distance [deg];
// nullopt when no keyframe qualifies. ViewWasSeen is this angle <= max_angle_deg.
std::optional<double> NearestViewAngleDeg(const Eigen::Isometry3d& world_from_photo,
                                          const Eigen::Vector3d& point_world,
                                          const std::vector<store::KeyframeInfo>& keyframes,
                                          double max_distance_ratio = 2.0);
// ViewWasSeen's rule on a NearestViewAngleDeg (with options.max_distance_ratio) already computed.
bool IsSeenAngle(const std::optional<double>& nearest_angle_deg, const ViewSeenOptions& options);
// The keyframes (their indices in `keyframes`) that each saw the view by ViewWasSeen's rule: the
// ones a retrieval should rank first for this photo.
std::vector<size_t> KeyframesSeeingView(const Eigen::Isometry3d& world_from_photo,
                                        const Eigen::Vector3d& point_world,
                                        const std::vector<store::KeyframeInfo>& keyframes,
                                        const ViewSeenOptions& options = ViewSeenOptions());

// {"share", "open_sectors", "seen_sectors", "up", "eye_height_m", "labels": [{"id", "name",
// "type", "centre", "share", "open_sectors", "seen_sectors", "keyframes", "sectors": [{"from_deg",
// "to_deg", "open", "seen", "keyframes", "nearest_m", "farthest_m", "open_distances_m"}]}]}:
// `sightmap coverage --json`.
nlohmann::json CoverageToJson(const ModelCoverage& coverage);

// A floor plan (BGR, the longer side max_side_px, the floor's second axis up the image):
// surfaces within 0.6 m of eye height dark, crossed space light, keyframes as blue dots; around
// each label its open sectors, green where seen, red where not, and its name.
cv::Mat DrawCoverage(const ModelCoverage& coverage, int max_side_px = 1200);

}  // namespace sightmap::identify
