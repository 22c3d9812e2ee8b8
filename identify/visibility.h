// Which labelled appliances a located photo shows: each label's points projected with the photo's
// pose, and tested for occlusion against the model's own surfaces (a coarse voxel cloud drawn into
// a z-buffer from the photo's pose). The paper projected only, so an appliance behind a wall was
// reported as in view (8.9% of its instances were such false positives).
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "identify/locator.h"
#include "store/model.h"

namespace sightmap::identify {

// The model's surfaces as voxel centres in the world frame [m]: what can hide an appliance.
struct OcclusionCloud {
  double voxel_m = 0.05;
  std::vector<Eigen::Vector3f> world_points;  // sorted by (x, y, z), as Build gives them
};

// One keyframe's depth at a small size, for telling from where the walk saw a label point.
struct SightingView {
  cv::Mat depth_mm;       // CV_16UC1
  Intrinsics intrinsics;  // at depth_mm's size
  Eigen::Isometry3d cam_from_world = Eigen::Isometry3d::Identity();
  // The part of depth_mm the sensor measured (MeasuredArea): depth registered to the colour
  // camera has none in bands along the image's edges, and missing depth there is not a sighting.
  // Empty = all of it: views built by hand, and a view that measured nothing at all (a window or
  // a screen filling the frame), whose missing depth counts as it always did.
  cv::Rect measured;
};

// The rectangle of `depth_mm` (CV_16UC1) between its first and last rows (columns) in which at
// least 5% of the pixels hold depth: the image less the bands along its edges where the sensor
// measured nothing. At 640x480, columns left / right and rows top / bottom: the 3dmatch lounge
// recording's Kinect 2-5 / 35-36 and 12 / 8, the simulator's 8 / 35 and 20 / 5. Empty when
// nothing was measured.
cv::Rect MeasuredArea(const cv::Mat& depth_mm);

// Which sighting views can see a point: each view's frustum, out to the farthest depth it measured,
// bounded by an axis-aligned box and entered in the cells of a grid of `cell_m` it overlaps. A
// point's candidates are the views of its cell (a superset of those that see it), so a test against
// every view becomes one against the few whose frusta reach the point: what the see-through check
// of a building's filled voxels needs, whose views and voxels both grow with the floor.
class ViewGrid {
 public:
  ViewGrid(const std::vector<SightingView>& views, double cell_m);
  // Indices into the views; empty when none reaches the point's cell.
  const std::vector<uint32_t>& ViewsNear(const Eigen::Vector3d& world_point) const;
  size_t entries() const { return entries_; }  // (view, cell) pairs

 private:
  double cell_m_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
  std::vector<uint32_t> none_;
  size_t entries_ = 0;
};

// Accumulates depth images into occupied voxels (a set, so each surface cell is kept once however
// many keyframes saw it).
class OcclusionCloudBuilder {
 public:
  explicit OcclusionCloudBuilder(double voxel_m);

  // Every `pixel_step`-th pixel (in both directions) of a depth image [mm] whose depth lies in
  // [min_depth_m, max_depth_m], unprojected with `intrinsics` (the depth image's size) and moved
  // to the world frame. Where the sensor returned nothing inside a surface (a screen, glass, a
  // black panel: a hole of those samples enclosed within max_hole_fill_samples of them on its
  // four sides, FillEnclosedHoles), the farthest of the enclosing depths stands in as a filled
  // voxel, so what lies behind a screen is hidden by it as by the wall around it (0: holes stay
  // empty). A doorway onto a room beyond the sensor's range is such a hole too: Build drops the
  // filled voxels that other keyframes saw through.
  void AddDepth(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                const Eigen::Isometry3d& world_from_cam, int pixel_step, double min_depth_m,
                double max_depth_m, int max_hole_fill_samples = 0);
  // One world point [m] (hand-built scenes in tests).
  void AddPoint(const Eigen::Vector3d& world_point);

  // Adds another builder's voxels (of the same size): one cloud from depth added on two threads.
  void Merge(const OcclusionCloudBuilder& other);

  size_t size() const { return voxels_.size(); }
  // The measured voxels and the filled ones no view saw through: a filled voxel goes when some
  // view's depth at its pixel lies more than see_through_margin_m beyond it [m].
  OcclusionCloud Build(const std::vector<SightingView>& views = {},
                       double see_through_margin_m = 0.15) const;

 private:
  double voxel_m_;
  std::unordered_set<uint64_t> voxels_;
  std::unordered_set<uint64_t> filled_voxels_;  // none of them in voxels_ when built
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
  // The margin above grows with distance (pose, voxel and grazing-angle errors), so a far
  // appliance on the other side of a wall (0.1-0.3 m in front of it) passed as visible. A label
  // point the walk saw from one side only is hidden from a camera on the other side: when at
  // least min_sighting_keyframes keyframes saw it (their depth there not nearer than the point by
  // more than sighting_depth_m, or missing with the point within sighting_max_m), their mean
  // unit ray (keyframe to point) is at least min_one_sidedness long, the photo's ray is more
  // than behind_angle_deg from it, and the z-buffer has a surface more than behind_margin_m in
  // front of the point [m], [m], [], [], [deg], [m]. On 200 session-2 photos this took the
  // occluded appliances reported as visible from 8 to 3 of 145, with no visible one lost.
  double sighting_depth_m = 0.10;
  double sighting_max_m = 4.5;
  int min_sighting_keyframes = 3;
  double min_one_sidedness = 0.8;
  double behind_angle_deg = 120.0;
  double behind_margin_m = 0.05;
  // Seen from behind, a point is hidden too where the z-buffer reaches past it to a surface more
  // than margin_m + margin_ratio x its depth beyond it: the photo looks through a wall whose far
  // side the walk did not see (or a screen's hole) into the next room, at an appliance hung on the
  // wall's other face. A free-standing appliance shows its own surface from any side; where
  // nothing at all is drawn (a ceiling the walk did not look at) nothing is known, and the
  // point stays visible.
  bool behind_needs_own_surface = true;
  // A free-standing appliance (IsFreeStanding: a projector hung from the ceiling, a lamp, a
  // monitor on a desk) is not hidden by a wall behind it: seen from behind it shows its own body,
  // which stands up to half its depth in front of its label point. From behind, such a point is
  // hidden only by a surface more than free_standing_behind_margin_m in front of it, not
  // behind_margin_m (so one standing within that of a wall shows through the wall from its far
  // side, as it does under the occlusion margin alone) [m].
  double free_standing_behind_margin_m = 0.25;
  // A surface in front of a point hides it only when it stands more than own_surface_m off the
  // plane the point sits on (0 turns this off): seen along a wall at a grazing angle, the wall's
  // measured thickness (depth noise and pose error put its voxels 5-15 cm proud of it) lies on
  // the line of sight for a metre before a switch or thermostat on it. The plane is the
  // occlusion cloud's within surface_radius_m of the point, where the cloud there is flat: its
  // least spread (the smallest eigenvalue of the voxels' covariance) at most
  // max_surface_flatness of the next; a lamp or a monitor on a desk has none. A camera within
  // own_surface_m of the plane sees it edge-on, and the rule does not apply [m], [m], [].
  double own_surface_m = 0.15;
  double surface_radius_m = 0.3;
  double max_surface_flatness = 0.1;

  bool Check(std::string* error) const;
};

// Whether a label's type names an appliance that stands free of the walls: its last word, after
// lower-casing and reading '_' and '-' as spaces, is projector, lamp, monitor or printer ("desk
// lamp", "Floor_Lamp"), and no word is "wall" ("wall lamp"). Other types (a switch, a thermostat,
// a TV, a screen, a ceiling light, any type not known here) hang on a wall or the ceiling, which
// hides them from behind.
bool IsFreeStanding(const std::string& type);

// From where the walk saw a label point: the mean of the unit rays (keyframe centre to point) of
// the keyframes with a clear line of sight to it (VisibilityOptions), and how many there were.
struct PointSighting {
  Eigen::Vector3d mean_ray = Eigen::Vector3d::Zero();  // length 1: all from one direction
  int keyframes = 0;
  // The unit normal (either sign) of the flat surface the point sits on, from the occlusion
  // cloud around it (SurfaceNormal); zero where the cloud there is not flat or not given.
  Eigen::Vector3d surface_normal = Eigen::Vector3d::Zero();
};
// Per label, per point.
using LabelSightings = std::vector<std::vector<PointSighting>>;

// Whether a keyframe has a clear line of sight to a point `point_z_m` in front of it, from its
// depth at the point's pixel (`seen_mm`, 0 when missing): the depth reaches the point, or beyond,
// within sighting_depth_m, or is missing with the point within the sensor's range sighting_max_m
// (a dark screen or a window returns no depth; SightLabels also needs the pixel inside the view's
// measured area) [m]. The one rule for the side the walk saw a point from: the sightings `locate`
// tells occlusion with, and the clicks of `label import --as-clicked`.
bool ClearSighting(uint16_t seen_mm, double point_z_m, double sighting_depth_m,
                   double sighting_max_m);

// `depth_mm` resized to `width` x `height` (nearest, so no depth is invented at edges).
SightingView MakeSightingView(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                              const Eigen::Isometry3d& world_from_cam, int width, int height);
// With `cloud`, each point's surface_normal too.
LabelSightings SightLabels(const std::vector<store::LabelRecord>& labels,
                           const std::vector<SightingView>& views, const VisibilityOptions& options,
                           const OcclusionCloud* cloud = nullptr);

// The unit normal of the occlusion cloud's plane within options.surface_radius_m of `world_point`
// (the least-spread direction of those voxels), or zero when fewer than 6 voxels lie there or
// they are not flat (VisibilityOptions::max_surface_flatness). The cloud's points must be sorted
// by x (they are searched in the slab of x the radius spans).
Eigen::Vector3d SurfaceNormal(const OcclusionCloud& cloud, const Eigen::Vector3d& world_point,
                              const VisibilityOptions& options);

// The cloud's depth [m] seen from `world_from_cam` through `intrinsics` (already at the z-buffer's
// resolution), +infinity where nothing was drawn. CV_32FC1.
cv::Mat RenderOcclusionDepth(const OcclusionCloud& cloud, const Intrinsics& intrinsics,
                             const Eigen::Isometry3d& world_from_cam,
                             const VisibilityOptions& options);

// Each +infinity pixel of a CV_32FC1 depth image with finite pixels at most `max_distance_px` away
// along its row on both sides and along its column on both sides takes the largest of those four
// depths (the nearest finite pixel in each direction, read before any filling). In place.
void FillEnclosedHoles(int max_distance_px, cv::Mat* depth);

// The labels in the view cone of a photo with `intrinsics` (full resolution) at `world_from_cam`,
// nearest first; occluded ones are kept with occluded = true. Without a cloud (nullptr or empty)
// nothing counts as occluded.
// With `sightings` (SightLabels' answer for `labels`), a point seen from behind its surface is
// occluded too.
std::vector<ApplianceInView> AppliancesInView(const std::vector<store::LabelRecord>& labels,
                                              const OcclusionCloud* cloud,
                                              const Intrinsics& intrinsics,
                                              const Eigen::Isometry3d& world_from_cam,
                                              const VisibilityOptions& options,
                                              const LabelSightings* sightings = nullptr);

}  // namespace sightmap::identify
