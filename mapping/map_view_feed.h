// The mapping session's side of render/: builds MapUpdates (keyframe clouds, corrected poses, loop
// edges, camera, status) and hands them to a MapView (preview window or progress images) without
// waiting. It is the one mapping file that includes render/ (OpenGL, GLFW, OSMesa): its plain
// types keep render/ a private dependency of mapping/, so the rest of the pipeline builds and is
// tested without a GL header in sight.
#pragma once

#include <cstdint>
#include <memory>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/link_type.h"
#include "core/tracking_state.h"
#include "store/model.h"

namespace sightmap::mapping {

enum class ViewChoice { kAuto, kPreview, kHeadless };

// The map draws the links that close loops or join parts; odometry and a blind run's motion
// priors lie along the track, which is drawn already.
bool DrawnAsLoop(LinkType type);

struct MapViewFeedOptions {
  ViewChoice choice = ViewChoice::kAuto;
  // Off-screen progress image, rewritten atomically every `progress_every_n_keyframes` keyframes
  // and at the end; empty = no file.
  std::string progress_png;
  int progress_every_n_keyframes = 10;
  // The mapper's world is the first camera's frame (x right, y down, z forward): up is -y.
  Eigen::Vector3d world_up = Eigen::Vector3d(0.0, -1.0, 0.0);
  // Every n-th pixel of a keyframe becomes a point of the preview's cloud, averaged in voxels of
  // `voxel_m` [px], [m].
  int cloud_pixel_step = 2;
  double cloud_voxel_m = 0.05;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const MapViewFeedOptions& options);
void from_json(const nlohmann::json& json, MapViewFeedOptions& options);

struct FeedStatus {
  int64_t keyframes = 0;
  int64_t loops = 0;
  TrackingState tracking = TrackingState::kTracking;
  double keyframes_per_s = 0.0;
  double elapsed_s = 0.0;
};

class MapViewFeed {
 public:
  // Opens the view CreateMapView picks for `options.choice`; `notices` gets the one-line fallback
  // notice (may be null). Throws sightmap::Error when a forced preview cannot open.
  static std::unique_ptr<MapViewFeed> Create(const MapViewFeedOptions& options,
                                             std::ostream* notices);
  ~MapViewFeed();
  MapViewFeed(const MapViewFeed&) = delete;
  MapViewFeed& operator=(const MapViewFeed&) = delete;

  // The model's labels, drawn on the map. Every keyframe added after this (restored ones too) is
  // checked for which of them it sees (in its image, not hidden behind its depth), so the floor
  // plan shows the directions each was seen from and those still missing (coverage while
  // mapping). Call before the first keyframe, from one thread.
  void SetLabels(const std::vector<store::LabelRecord>& labels);
  // A keyframe's cloud from its registered BGR + depth [mm]; `session` >= 1 colours its track.
  void AddKeyframe(int64_t id, int session, const Eigen::Isometry3d& world_from_cam,
                   const cv::Mat& bgr, const cv::Mat& depth_mm, const Intrinsics& intrinsics);
  void UpdatePoses(const std::vector<std::pair<int64_t, Eigen::Isometry3d>>& world_from_cam);
  void AddLoop(int64_t from_id, int64_t to_id);
  // A loop drawn before and switched off since (or one of two drawn with the same ends).
  void RemoveLoop(int64_t from_id, int64_t to_id);
  void SetCamera(const Eigen::Isometry3d& world_from_cam);
  void SetStatus(const FeedStatus& status);
  void SetLiveImages(const cv::Mat& bgr, const cv::Mat& depth_mm);

  bool paused() const;
  bool stop_requested() const;
  // Draws the final state (writes the final progress image) and waits for it.
  void Finish();
  std::string description() const;

 private:
  struct Impl;
  explicit MapViewFeed(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::mapping
