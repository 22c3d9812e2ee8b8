// The synthetic building: renders the walk's RGB-D frames and the users' phone photos with
// ground truth (poses, and per photo the visibility type of every appliance).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/rgbd_frame.h"
#include "render/mesh_renderer.h"
#include "sim/scene.h"
#include "sim/sensor_model.h"
#include "sim/trajectory.h"

namespace sightmap::sim {

// A Kinect v1 colour camera (the TUM RGB-D default intrinsics).
Intrinsics KinectIntrinsics();

struct SimulatorOptions {
  std::string scene = "office";  // "office" (embedded) or a scene JSON file
  TrajectoryKind trajectory = TrajectoryKind::kHandheld;
  int session = 1;    // >= 1: lighting, chair positions and the start differ per session
  uint64_t seed = 1;  // same options and seed => identical frames and photos, byte for byte
  double fps = 30.0;  // frame rate of the produced stream [Hz]; 1 renders only 1 Hz frames
  // Frames to produce; -1 = default_duration_s of walk at `fps` (a survey: one lap).
  int64_t frames = -1;
  double default_duration_s = 300.0;  // [s], a few laps of the office (~300 1 Hz keyframes)
  Intrinsics camera = KinectIntrinsics();
  DepthSensorOptions depth;
  ColorSensorOptions color;

  bool Check(std::string* error) const;
};

// Ground-truth visibility of one appliance in one photo, from the appliance-ID buffer rendered at
// 1/VisibilityThresholds::id_buffer_downscale of the photo's resolution:
//   footprint  = pixels the appliance covers drawn alone (no occluders) on a canvas three times
//                the image in each direction (so parts outside the image are counted),
//   in_image   = the part of the footprint inside the image,
//   visible_px = pixels of the appliance in the full scene's ID buffer (occluders drawn).
// Types:
//   not_visible        in_image < min_pixels (outside the view cone, behind or too small)
//   occluded           visible_px < occluded_below * in_image (inside the view cone but hidden)
//   visible            visible_px >= visible_from * footprint
//   partially_visible  otherwise (cut by the image border or partly hidden)
enum class VisibilityType { kNotVisible, kOccluded, kPartiallyVisible, kVisible };
const char* ToString(VisibilityType type);

struct VisibilityThresholds {
  int id_buffer_downscale = 4;   // ID buffers at 1/N resolution (counts are in those pixels)
  int min_pixels = 4;            // smaller footprints in the image count as not visible
  double occluded_below = 0.10;  // visible share of the in-image footprint below which hidden
  double visible_from = 0.85;    // visible share of the whole footprint that counts as visible

  bool Check(std::string* error) const;
};

struct ApplianceVisibility {
  int appliance_id = 0;
  VisibilityType type = VisibilityType::kNotVisible;
  int footprint_px = 0;
  int in_image_px = 0;
  int visible_px = 0;
};

struct QueryOptions {
  int width = 1280;  // phone image size [px]
  int height = 960;
  double hfov_deg = 65.0;       // horizontal field of view [deg]
  double min_distance_m = 0.8;  // camera to the target appliance [m]
  double max_distance_m = 4.0;
  double min_height_m = 1.0;  // camera height [m]
  double max_height_m = 1.9;
  double max_yaw_jitter_deg = 12.0;   // aim error left/right [deg]
  double max_pitch_jitter_deg = 8.0;  // aim error up/down [deg]
  double max_roll_deg = 15.0;         // phone tilt [deg]
  double occluder_share = 0.25;  // share of photos taken with furniture between camera and target
  // A photo whose target the furniture hides entirely (or that shows it too small to count, see
  // VisibilityThresholds) is drawn again, up to this many times: a person photographs what they
  // can see. Without it 18 of 200 session-2 photos (seed 7) showed none of their target, e.g. a
  // monitor behind a plant box filling half of the frame. At most 255.
  int max_hidden_target_redraws = 20;
  // A person photographing something overhead (a ceiling light) holds the phone level-ish: they
  // step back until it is at most overhead_max_elevation_deg above the horizon, and aim
  // overhead_frame_offset_deg below it, so it sits in the upper part of the frame (a 65 x 51 deg
  // phone: half-way between the centre and the top) with the room's walls and furniture below it,
  // not a view straight up at a bare ceiling. Targets above overhead_min_height_m are overhead
  // [deg], [deg], [m].
  double overhead_max_elevation_deg = 40.0;
  double overhead_frame_offset_deg = 13.0;
  double overhead_min_height_m = 2.3;
  VisibilityThresholds thresholds;

  bool Check(std::string* error) const;
  Intrinsics PhoneIntrinsics() const;
};

struct QueryPhoto {
  int index = 0;
  int target_appliance = 0;    // the appliance the photo was aimed at (its id)
  bool with_occluder = false;  // sampled with furniture on the line of sight
  Intrinsics intrinsics;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  cv::Mat image;                                // BGR
  std::vector<ApplianceVisibility> visibility;  // one per appliance, in scene order
};
// Whether a photo with this visibility (QueryPhoto::visibility) shows the appliance
// `appliance_id`, wholly or in part (a person photographs an appliance they can see).
bool ShowsAppliance(const std::vector<ApplianceVisibility>& visibility, int appliance_id);

class Simulator {
 public:
  explicit Simulator(const SimulatorOptions& options);
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  const SimulatorOptions& options() const { return options_; }
  // The scene as this session sees it (chairs moved).
  const Scene& scene() const { return scene_; }
  const Trajectory& trajectory() const { return *trajectory_; }
  int64_t num_frames() const { return num_frames_; }

  TimestampNs TimestampOf(int64_t index) const;
  Eigen::Isometry3d WorldFromCam(int64_t index) const;
  // Frame `index` (0-based) of the walk; independent of which frames were rendered before.
  RgbdFrame RenderFrame(int64_t index);

  // `count` phone photos aimed at the appliances in turn (reproducible from the seed).
  std::vector<QueryPhoto> MakeQueries(int count, const QueryOptions& options);
  // Renders one photo and its ground truth from a given pose (hand-built test cases).
  QueryPhoto RenderQuery(const Intrinsics& intrinsics, const Eigen::Isometry3d& world_from_cam,
                         const VisibilityThresholds& thresholds, uint64_t noise_seed);
  std::vector<ApplianceVisibility> ClassifyAppliances(const Intrinsics& intrinsics,
                                                      const Eigen::Isometry3d& world_from_cam,
                                                      const VisibilityThresholds& thresholds);

  render::MeshRenderer& renderer() { return *renderer_; }

 private:
  // RenderQuery's photo without its visibility: MakeQueries classifies a draw before it renders
  // it, and renders only the draw it keeps.
  QueryPhoto RenderQueryImage(const Intrinsics& intrinsics, const Eigen::Isometry3d& world_from_cam,
                              uint64_t noise_seed);
  SimulatorOptions options_;
  Scene scene_;
  std::unique_ptr<Trajectory> trajectory_;
  std::unique_ptr<render::MeshRenderer> renderer_;
  int64_t num_frames_ = 0;
  double exposure_phase_ = 0.0;
};

// A top-down floor plan (walls, furniture, appliances with names, the trajectory and the photo
// positions), `pixels_per_m` pixels per metre, BGR.
cv::Mat DrawOverview(const Scene& scene, const std::vector<Eigen::Isometry3d>& trajectory,
                     const std::vector<QueryPhoto>& queries, double pixels_per_m = 40.0);

}  // namespace sightmap::sim
