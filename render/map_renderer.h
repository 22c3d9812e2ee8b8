// Draws the map (coloured keyframe points, trajectories coloured by session, loop edges, the
// current camera's frustum, labelled appliances, a status overlay) with legacy OpenGL into the
// context current on the calling thread: the off-screen progress writer's OSMesa context or the
// preview window's GLFW context.
//
// Each keyframe's points live in one vertex buffer in the keyframe's camera frame and are drawn
// with its world_from_cam as model matrix: Sync() uploads only keyframes whose points are new or
// replaced, and a pose update (loop closure) costs no upload.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "render/gl_proc.h"
#include "render/map_scene.h"

namespace sightmap::render {

struct MapRenderOptions {
  int width = 1280;  // progress image [px]: floor plan on the left half, camera view on the right
  int height = 720;
  float point_size_px = 2.0f;  // map points [px]
  // Level of detail: a view draws at most this many points per pixel of its viewport (of the
  // keyframes inside its view volume), a uniform random subset of each keyframe (points are
  // uploaded in shuffled order, so the subset is a prefix). 0 = draw every point. The software
  // rasterizer's cost grows with the points that reach the screen; a floor plan of 5M points
  // has some 10 of them per pixel, which add nothing to the picture.
  double max_points_per_pixel = 0.5;
  float trajectory_width_px = 2.0f;
  int text_scale = 2;             // screen pixels per font pixel
  double top_down_margin = 0.04;  // share of the floor-plan panel left free on each side
  // The floor plan cuts points higher than the highest camera + this [m] (ceilings, lamps), and
  // darkens points by their depth below the cut (walls bright, floor dim): floor_brightness is the
  // brightness kept at the lowest point, in [0, 1]; 1 = no depth cue.
  double top_down_cut_above_camera_m = 0.4;
  double floor_brightness = 0.6;
  // The camera view: from follow_distance_m behind and follow_height_m above the current camera,
  // looking look_ahead_m ahead of it.
  double follow_distance_m = 3.5;
  double follow_height_m = 2.0;
  double look_ahead_m = 1.5;
  double follow_hfov_deg = 75.0;
  double frustum_depth_m = 0.4;  // drawn size of the current camera's frustum [m]
  Eigen::Vector3f background_rgb = Eigen::Vector3f(0.07f, 0.07f, 0.09f);  // [0, 1]
  // Around each appliance on the floor plan, a ring of sectors: green where a keyframe saw it
  // from, red where none has yet (MapScene::SeenSectors). Drawn when the scene has appliances.
  bool show_coverage = true;
  SectorOptions coverage;

  bool Check(std::string* error) const;
};

// A view of the map in the OpenCV convention (x right, y down, z forward), either a pinhole camera
// or an orthographic one. Orthographic: fx, fy are pixels per metre, u = cx + fx * x_cam and
// v = cy + fy * y_cam. Pixel centres at integer coordinates, (0, 0) = the view's top-left pixel.
struct ViewCamera {
  Intrinsics intrinsics;  // width, height = the viewport size
  bool orthographic = false;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  double near_m = 0.05;  // clipping range along z_cam [m]
  double far_m = 200.0;
  // > 0: points fade towards the background over this distance along z_cam [m] (floor plans).
  double depth_cue_m = 0.0;

  // Pixel of a world point; nullopt when it is outside the clipping range.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& world_point) const;
  // The same without the clipping range when orthographic (where a point lies on the plan,
  // whatever its height).
  std::optional<Eigen::Vector2d> ProjectOnPlan(const Eigen::Vector3d& world_point) const;
};

// The status block's coverage line, "labels N  seen from S of M directions" (M = N x sectors);
// empty without labels.
std::string CoverageLine(const MapScene& scene, const SectorOptions& options);

// The floor plan: looking down world_up from the cut height, fit to the map's extent and centred.
// Horizontal axes: x_world projected on the floor is image-right, up x that is image-up.
ViewCamera TopDownCamera(const MapScene& scene, int width, int height,
                         const MapRenderOptions& options);
// Behind and above the current camera (or the last keyframe), looking ahead of it.
ViewCamera FollowCamera(const MapScene& scene, int width, int height,
                        const MapRenderOptions& options);
// Around `target` at `distance_m`; yaw about world_up from the floor's x axis, pitch above the
// floor (clamped to +-89 degrees) [rad].
ViewCamera OrbitCamera(const Eigen::Vector3d& target, double yaw_rad, double pitch_rad,
                       double distance_m, const Eigen::Vector3d& world_up, int width, int height,
                       double hfov_deg);

// A rectangle of the framebuffer in pixels, (x, y) = its top-left corner, y down.
struct Viewport {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

class MapRenderer {
 public:
  // Uses the GL context current on the calling thread, reached through `loader` (e.g.
  // OffscreenContext::ProcAddress or glfwGetProcAddress). Create, use and destroy the renderer on
  // that thread with that context current. Throws sightmap::Error if a GL entry point is missing.
  explicit MapRenderer(GlProcLoader loader, const MapRenderOptions& options = MapRenderOptions());
  ~MapRenderer();
  MapRenderer(const MapRenderer&) = delete;
  MapRenderer& operator=(const MapRenderer&) = delete;

  const MapRenderOptions& options() const;

  // Uploads the points of keyframes that are new or replaced since the last call and frees the
  // buffers of keyframes no longer in the scene.
  void Sync(const MapScene& scene);
  // Keyframe uploads and points uploaded so far (counters for tests and logs).
  size_t num_uploads() const;
  size_t num_uploaded_points() const;
  // Points submitted to GL by the last DrawMap (after view-volume culling and level of detail).
  size_t num_points_drawn() const;

  // Starts a frame: clears the whole framebuffer (width x height [px]) to the background.
  void BeginFrame(int framebuffer_width, int framebuffer_height);
  // The map seen by `view` in `viewport` (whose size should match the view's intrinsics). Sync()
  // first: keyframes not yet uploaded are not drawn.
  void DrawMap(const MapScene& scene, const ViewCamera& view, const Viewport& viewport);
  // Keyframes, loops, points, tracking state, keyframes per second and elapsed time, top-left.
  void DrawStatus(const MapScene& scene, const Viewport& viewport);
  // A metric scale bar for an orthographic view, bottom-left of the viewport.
  void DrawScaleBar(const ViewCamera& view, const Viewport& viewport);
  // Text in framebuffer pixels (top-left corner at x, y), with a dark backing for contrast.
  void DrawText(std::string_view text, int x, int y, int scale, const Eigen::Vector3f& rgb);
  // An 8-bit BGR or grey image fitted into the viewport, aspect kept.
  void DrawImage(const cv::Mat& image, const Viewport& viewport);

  // The progress picture: Sync, then the floor plan (left half) and the follow view (right half)
  // with the status overlay and panel titles, into a width x height framebuffer.
  void DrawProgress(const MapScene& scene, int width, int height);
  // The framebuffer as BGR, top row first (waits for GL to finish).
  cv::Mat ReadImage(int width, int height);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The two views DrawProgress draws, for callers that need their projections (tests, labels).
struct ProgressLayout {
  Viewport top_down_viewport;
  ViewCamera top_down;
  Viewport follow_viewport;
  ViewCamera follow;
};
ProgressLayout MakeProgressLayout(const MapScene& scene, int width, int height,
                                  const MapRenderOptions& options);

}  // namespace sightmap::render
