// Which labelled appliances a located photo shows: each label's points projected with the photo's
// pose, and tested for occlusion against the model's own surfaces (a coarse voxel cloud drawn into
// a z-buffer from the photo's pose). The paper projected only, so an appliance behind a wall was
// reported as in view (8.9% of its instances were such false positives).
#pragma once

#include <cstdint>
#include <string>
#include <unordered_set>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "identify/locator.h"
#include "store/model.h"

namespace sightmap {

// The model's surfaces as voxel centres in the world frame [m]: what can hide an appliance.
struct OcclusionCloud {
  double voxel_m = 0.05;
  std::vector<Eigen::Vector3f> world_points;
};

// Accumulates depth images into occupied voxels (a set, so each surface cell is kept once however
// many keyframes saw it).
class OcclusionCloudBuilder {
 public:
  explicit OcclusionCloudBuilder(double voxel_m);

  // Every `pixel_step`-th pixel (in both directions) of a depth image [mm] whose depth lies in
  // [min_depth_m, max_depth_m], unprojected with `intrinsics` (the depth image's size) and moved
  // to the world frame.
  void AddDepth(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                const Eigen::Isometry3d& world_from_cam, int pixel_step, double min_depth_m,
                double max_depth_m);
  // One world point [m] (hand-built scenes in tests).
  void AddPoint(const Eigen::Vector3d& world_point);

  size_t size() const { return voxels_.size(); }
  OcclusionCloud Build() const;

 private:
  double voxel_m_;
  std::unordered_set<uint64_t> voxels_;
};

struct VisibilityOptions {
  // The z-buffer is drawn at 1/zbuffer_downscale of the photo's resolution.
  int zbuffer_downscale = 8;
  // A point is occluded when the cloud has a surface nearer than it by more than
  // margin_m + margin_ratio x its depth [m], []. Label points sit on their appliance's surface
  // (or inside it: a lamp's point is the centre of its shade), which is itself in the cloud:
  // the margin keeps an appliance from hiding itself.
  double margin_m = 0.15;
  double margin_ratio = 0.05;
  // Cloud points nearer than this to the camera are not drawn (the camera stands in free space;
  // a voxel it stands in would cover the whole image) [m].
  double near_m = 0.2;
  // A voxel's splat spans splat_scale x its projected size, so a surface has no holes; capped at
  // max_splat_radius_px z-buffer pixels.
  double splat_scale = 1.0;
  int max_splat_radius_px = 6;
  // In view when at least this share of the label's points project inside the image in front of
  // the camera; visible when at least this share of those are not occluded.
  double min_in_view_share = 0.5;
  double min_unoccluded_share = 0.5;

  bool Check(std::string* error) const;
};

// The cloud's depth [m] seen from `world_from_cam` through `intrinsics` (already at the z-buffer's
// resolution), +infinity where nothing was drawn. CV_32FC1.
cv::Mat RenderOcclusionDepth(const OcclusionCloud& cloud, const Intrinsics& intrinsics,
                             const Eigen::Isometry3d& world_from_cam,
                             const VisibilityOptions& options);

// The labels in the view cone of a photo with `intrinsics` (full resolution) at `world_from_cam`,
// nearest first; occluded ones are kept with occluded = true. Without a cloud (nullptr or empty)
// nothing counts as occluded.
std::vector<ApplianceInView> AppliancesInView(const std::vector<LabelRecord>& labels,
                                              const OcclusionCloud* cloud,
                                              const Intrinsics& intrinsics,
                                              const Eigen::Isometry3d& world_from_cam,
                                              const VisibilityOptions& options);

}  // namespace sightmap
