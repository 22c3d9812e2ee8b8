#include "identify/visibility.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "core/voxel_key.h"

namespace sightmap::identify {
namespace {

// The see-through check's grid of view frusta: a 1 m cell holds a few of a room's views; smaller
// cells multiply the entries of a view's frustum (~8 m deep) by the cube of the ratio.
constexpr double kViewGridCellM = 1.0;

}  // namespace

OcclusionCloudBuilder::OcclusionCloudBuilder(double voxel_m) : voxel_m_(voxel_m) {
  SIGHTMAP_CHECK(voxel_m > 0.0, "the occlusion cloud's voxel size must be positive");
}

void OcclusionCloudBuilder::AddDepth(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                                     const Eigen::Isometry3d& world_from_cam, int pixel_step,
                                     double min_depth_m, double max_depth_m,
                                     int max_hole_fill_samples) {
  if (depth_mm.empty()) return;
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1, "occlusion cloud: depth must be 16-bit [mm]");
  SIGHTMAP_CHECK(pixel_step >= 1, "occlusion cloud: pixel step must be at least 1");
  SIGHTMAP_CHECK(max_hole_fill_samples >= 0, "occlusion cloud: hole reach must not be negative");
  // Depth stored at another size than the intrinsics (never by the mapper, but cheap to allow).
  const Intrinsics k = (depth_mm.cols == intrinsics.width && depth_mm.rows == intrinsics.height)
                           ? intrinsics
                           : intrinsics.Scaled(depth_mm.cols, depth_mm.rows);
  // The sampled pixels [m], +infinity where the sensor returned nothing.
  const int first = pixel_step / 2;
  cv::Mat samples((depth_mm.rows - first + pixel_step - 1) / pixel_step,
                  (depth_mm.cols - first + pixel_step - 1) / pixel_step, CV_32FC1);
  for (int sv = 0; sv < samples.rows; ++sv) {
    const uint16_t* row = depth_mm.ptr<uint16_t>(first + sv * pixel_step);
    float* out = samples.ptr<float>(sv);
    for (int su = 0; su < samples.cols; ++su) {
      const uint16_t mm = row[first + su * pixel_step];
      out[su] = mm == 0 ? std::numeric_limits<float>::infinity() : mm * 1e-3f;
    }
  }
  // Without filling, both name the same samples.
  cv::Mat filled = max_hole_fill_samples > 0 ? samples.clone() : samples;
  FillEnclosedHoles(max_hole_fill_samples, &filled);
  // Neighbouring samples mostly share a voxel (at 1 m, 6 x 6 of them with a step of 4): the keys
  // are made unique per image before they enter the sets.
  std::vector<uint64_t> measured_keys;
  std::vector<uint64_t> filled_keys;
  measured_keys.reserve(static_cast<size_t>(samples.total()));
  for (int sv = 0; sv < samples.rows; ++sv) {
    const float* measured = samples.ptr<float>(sv);
    const float* row = filled.ptr<float>(sv);
    for (int su = 0; su < samples.cols; ++su) {
      const double z = row[su];
      if (!(z >= min_depth_m && z <= max_depth_m)) continue;
      const Eigen::Vector3d world =
          world_from_cam * k.Unproject(first + su * pixel_step, first + sv * pixel_step, z);
      if (const std::optional<uint64_t> key = VoxelKeyOf(world, voxel_m_)) {
        (std::isfinite(measured[su]) ? measured_keys : filled_keys).push_back(*key);
      }
    }
  }
  for (std::vector<uint64_t>* keys : {&measured_keys, &filled_keys}) {
    std::sort(keys->begin(), keys->end());
    keys->erase(std::unique(keys->begin(), keys->end()), keys->end());
  }
  voxels_.insert(measured_keys.begin(), measured_keys.end());
  filled_voxels_.insert(filled_keys.begin(), filled_keys.end());
}

void OcclusionCloudBuilder::Merge(const OcclusionCloudBuilder& other) {
  SIGHTMAP_CHECK(other.voxel_m_ == voxel_m_, "occlusion clouds of different voxel sizes ("
                                                 << voxel_m_ << " and " << other.voxel_m_
                                                 << " m) cannot be merged");
  voxels_.insert(other.voxels_.begin(), other.voxels_.end());
  filled_voxels_.insert(other.filled_voxels_.begin(), other.filled_voxels_.end());
}

void OcclusionCloudBuilder::AddPoint(const Eigen::Vector3d& world_point) {
  if (const std::optional<uint64_t> key = VoxelKeyOf(world_point, voxel_m_)) voxels_.insert(*key);
}

namespace {

// A world point as a sighting view sees it: in the view's frame [m], and the view's depth at its
// pixel [mm] (0: none measured).
struct ViewedPoint {
  Eigen::Vector3d in_view;
  uint16_t seen_mm = 0;
  cv::Point pixel;
};

// Nothing when the point lies behind the view or outside its image.
std::optional<ViewedPoint> PointInView(const SightingView& view,
                                       const Eigen::Vector3d& world_point) {
  const Eigen::Vector3d cam = view.cam_from_world * world_point;
  if (!(cam.z() > 0.0)) return std::nullopt;
  const Eigen::Vector2d pixel = view.intrinsics.Project(cam);
  const int u = static_cast<int>(std::lround(pixel.x()));
  const int v = static_cast<int>(std::lround(pixel.y()));
  if (u < 0 || v < 0 || u >= view.depth_mm.cols || v >= view.depth_mm.rows) return std::nullopt;
  return ViewedPoint{cam, view.depth_mm.at<uint16_t>(v, u), cv::Point(u, v)};
}

// Whether some view's depth at `world_point`'s pixel lies more than `margin_m` beyond it: that
// view saw through the point, so nothing stands there. Only the views `grid` lists near it can.
bool SeenThrough(const Eigen::Vector3d& world_point, const std::vector<SightingView>& views,
                 const ViewGrid& grid, double margin_m) {
  for (const uint32_t v : grid.ViewsNear(world_point)) {
    const std::optional<ViewedPoint> seen = PointInView(views[v], world_point);
    if (seen && seen->seen_mm != 0 && seen->seen_mm * 1e-3 > seen->in_view.z() + margin_m) {
      return true;
    }
  }
  return false;
}

// The cell coordinates of p in a grid of cell_m.
Eigen::Vector3i CellOf(const Eigen::Vector3d& p, double cell_m) {
  return (p / cell_m).array().floor().cast<int>();
}

}  // namespace

ViewGrid::ViewGrid(const std::vector<SightingView>& views, double cell_m) : cell_m_(cell_m) {
  SIGHTMAP_CHECK(cell_m > 0.0, "the view grid's cell size must be positive");
  SIGHTMAP_CHECK(views.size() < std::numeric_limits<uint32_t>::max(), "too many sighting views");
  for (size_t v = 0; v < views.size(); ++v) {
    const SightingView& view = views[v];
    double max_mm = 0.0;
    if (!view.depth_mm.empty()) cv::minMaxLoc(view.depth_mm, nullptr, &max_mm);
    if (max_mm <= 0.0) continue;  // measured nothing: sees through nothing
    // The frustum is the hull of the centre and the image's corners at the farthest depth.
    const Eigen::Isometry3d world_from_cam = view.cam_from_world.inverse();
    const double far_m = max_mm * 1e-3;
    Eigen::AlignedBox3d box(world_from_cam.translation());
    const int w = view.depth_mm.cols;
    const int h = view.depth_mm.rows;
    for (const auto& [u, v_px] : {std::pair{-0.5, -0.5}, std::pair{w - 0.5, -0.5},
                                  std::pair{-0.5, h - 0.5}, std::pair{w - 0.5, h - 0.5}}) {
      box.extend(world_from_cam * view.intrinsics.Unproject(u, v_px, far_m));
    }
    // A view on a wild pose (nothing indoors lies beyond the keys' range) reaches no cell.
    if (!VoxelKeyOf(box.min(), cell_m_) || !VoxelKeyOf(box.max(), cell_m_)) continue;
    const Eigen::Vector3i lo = CellOf(box.min(), cell_m_);
    const Eigen::Vector3i hi = CellOf(box.max(), cell_m_);
    for (int x = lo.x(); x <= hi.x(); ++x) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int z = lo.z(); z <= hi.z(); ++z) {
          const Eigen::Vector3d centre = (Eigen::Vector3d(x, y, z).array() + 0.5) * cell_m_;
          if (const std::optional<uint64_t> key = VoxelKeyOf(centre, cell_m_)) {
            cells_[*key].push_back(static_cast<uint32_t>(v));
            ++entries_;
          }
        }
      }
    }
  }
}

const std::vector<uint32_t>& ViewGrid::ViewsNear(const Eigen::Vector3d& world_point) const {
  const std::optional<uint64_t> key = VoxelKeyOf(world_point, cell_m_);
  if (!key) return none_;
  const auto cell = cells_.find(*key);
  return cell == cells_.end() ? none_ : cell->second;
}

OcclusionCloud OcclusionCloudBuilder::Build(const std::vector<SightingView>& views,
                                            double see_through_margin_m) const {
  SIGHTMAP_CHECK(see_through_margin_m >= 0.0, "see_through_margin_m must not be negative");
  OcclusionCloud cloud;
  cloud.voxel_m = voxel_m_;
  cloud.world_points.reserve(voxels_.size());
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(0.5 * voxel_m_);
  for (uint64_t key : voxels_) {
    cloud.world_points.push_back((VoxelCorner(key, voxel_m_) + half).cast<float>());
  }
  // Each filled voxel is checked against the views whose frusta reach it, spread over the cores,
  // each voxel's verdict in its own slot.
  std::vector<Eigen::Vector3d> filled;
  filled.reserve(filled_voxels_.size());
  for (uint64_t key : filled_voxels_) {
    if (voxels_.count(key) == 0) filled.push_back(VoxelCorner(key, voxel_m_) + half);
  }
  std::vector<uint8_t> kept(filled.size(), 0);
  const ViewGrid grid(views, kViewGridCellM);
  cv::parallel_for_(cv::Range(0, static_cast<int>(filled.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      kept[static_cast<size_t>(i)] =
          SeenThrough(filled[static_cast<size_t>(i)], views, grid, see_through_margin_m) ? 0 : 1;
    }
  });
  for (size_t i = 0; i < filled.size(); ++i) {
    if (kept[i] != 0) cloud.world_points.push_back(filled[i].cast<float>());
  }
  // Sorted so the same model gives the same cloud whatever the hash order (reproducible answers).
  std::sort(cloud.world_points.begin(), cloud.world_points.end(),
            [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
              return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
            });
  return cloud;
}

bool VisibilityOptions::Check(std::string* error) const {
  const char* why = nullptr;
  if (zbuffer_downscale < 1)
    why = "zbuffer_downscale must be at least 1";
  else if (margin_m < 0.0 || margin_ratio < 0.0)
    why = "occlusion margins must not be negative";
  else if (!(near_m > 0.0))
    why = "near_m must be positive";
  else if (!(splat_scale > 0.0) || max_splat_radius_px < 0)
    why = "splat_scale must be positive and max_splat_radius_px not negative";
  else if (!(min_in_view_share > 0.0 && min_in_view_share <= 1.0) ||
           !(min_unoccluded_share > 0.0 && min_unoccluded_share <= 1.0))
    why = "min_in_view_share and min_unoccluded_share must be in (0, 1]";
  else if (!(sighting_depth_m > 0.0) || !(sighting_max_m > 0.0) || min_sighting_keyframes < 1 ||
           !(min_one_sidedness >= 0.0 && min_one_sidedness <= 1.0) ||
           !(behind_angle_deg >= 90.0 && behind_angle_deg <= 180.0) || behind_margin_m < 0.0 ||
           free_standing_behind_margin_m < behind_margin_m)
    why =
        "sighting_depth_m, sighting_max_m and min_sighting_keyframes must be positive, "
        "min_one_sidedness in [0, 1], behind_angle_deg in [90, 180], behind_margin_m not "
        "negative, free_standing_behind_margin_m not below behind_margin_m";
  else if (own_surface_m < 0.0 || !(surface_radius_m > 0.0) ||
           !(max_surface_flatness >= 0.0 && max_surface_flatness <= 1.0))
    why =
        "own_surface_m must not be negative, surface_radius_m positive, max_surface_flatness in "
        "[0, 1]";
  if (why == nullptr) return true;
  if (error != nullptr) *error = std::string("VisibilityOptions: ") + why;
  return false;
}

cv::Mat RenderOcclusionDepth(const OcclusionCloud& cloud, const Intrinsics& intrinsics,
                             const Eigen::Isometry3d& world_from_cam,
                             const VisibilityOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const float inf = std::numeric_limits<float>::infinity();
  cv::Mat depth(intrinsics.height, intrinsics.width, CV_32FC1, cv::Scalar(inf));
  const Eigen::Isometry3f cam_from_world = world_from_cam.inverse().cast<float>();
  const Eigen::Matrix3f rotation = cam_from_world.linear();
  const Eigen::Vector3f translation = cam_from_world.translation();
  const float fx = static_cast<float>(intrinsics.fx);
  const float fy = static_cast<float>(intrinsics.fy);
  const float cx = static_cast<float>(intrinsics.cx);
  const float cy = static_cast<float>(intrinsics.cy);
  const float near = static_cast<float>(options.near_m);
  // Half the projected voxel at unit depth [px m]: radius = half_size / z.
  const float half_size = static_cast<float>(0.5 * options.splat_scale * cloud.voxel_m *
                                             std::max(intrinsics.fx, intrinsics.fy));
  const int max_radius = options.max_splat_radius_px;
  const int w = intrinsics.width;
  const int h = intrinsics.height;
  for (const Eigen::Vector3f& world_point : cloud.world_points) {
    const Eigen::Vector3f p = rotation * world_point + translation;
    const float z = p.z();
    if (z < near) continue;
    const float u = fx * p.x() / z + cx;
    const float v = fy * p.y() / z + cy;
    const int radius = std::min(max_radius, static_cast<int>(half_size / z + 0.5f));
    const int u0 = static_cast<int>(std::lround(u));
    const int v0 = static_cast<int>(std::lround(v));
    if (u0 + radius < 0 || u0 - radius >= w || v0 + radius < 0 || v0 - radius >= h) continue;
    const int ua = std::max(0, u0 - radius);
    const int ub = std::min(w - 1, u0 + radius);
    const int va = std::max(0, v0 - radius);
    const int vb = std::min(h - 1, v0 + radius);
    for (int y = va; y <= vb; ++y) {
      float* row = depth.ptr<float>(y);
      for (int x = ua; x <= ub; ++x) row[x] = std::min(row[x], z);
    }
  }
  return depth;
}

void FillEnclosedHoles(int max_distance_px, cv::Mat* depth) {
  SIGHTMAP_CHECK(depth != nullptr && depth->type() == CV_32FC1, "a CV_32FC1 depth image");
  SIGHTMAP_CHECK(max_distance_px >= 0, "max_distance_px must not be negative");
  if (max_distance_px == 0 || depth->empty()) return;
  const int w = depth->cols;
  const int h = depth->rows;
  const float inf = std::numeric_limits<float>::infinity();
  // Per pixel, the farthest of the nearest finite depths in the directions scanned so far;
  // +infinity once some direction has none within reach.
  cv::Mat enclosing(h, w, CV_32FC1, cv::Scalar(-inf));
  // Walks `count` pixels from (x, y) by (dx, dy), recording for each hole pixel the nearest
  // finite depth behind it on that line.
  auto scan = [&](int x, int y, int dx, int dy, int count) {
    float last = inf;
    int since = max_distance_px + 1;
    for (int i = 0; i < count; ++i, x += dx, y += dy) {
      const float d = depth->at<float>(y, x);
      if (std::isfinite(d)) {
        last = d;
        since = 0;
        continue;
      }
      ++since;
      float& t = enclosing.at<float>(y, x);
      t = since <= max_distance_px ? std::max(t, last) : inf;
    }
  };
  for (int y = 0; y < h; ++y) {
    scan(0, y, 1, 0, w);
    scan(w - 1, y, -1, 0, w);
  }
  for (int x = 0; x < w; ++x) {
    scan(x, 0, 0, 1, h);
    scan(x, h - 1, 0, -1, h);
  }
  for (int y = 0; y < h; ++y) {
    float* row = depth->ptr<float>(y);
    const float* fill = enclosing.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      if (!std::isfinite(row[x]) && std::isfinite(fill[x])) row[x] = fill[x];
    }
  }
}

SightingView MakeSightingView(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                              const Eigen::Isometry3d& world_from_cam, int width, int height) {
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 && width > 0 && height > 0,
                 "a sighting view needs 16-bit depth [mm] and a positive size");
  SightingView view;
  cv::resize(depth_mm, view.depth_mm, cv::Size(width, height), 0.0, 0.0, cv::INTER_NEAREST);
  view.intrinsics = intrinsics.Scaled(width, height);
  view.cam_from_world = world_from_cam.inverse();
  view.measured = MeasuredArea(view.depth_mm);
  return view;
}

cv::Rect MeasuredArea(const cv::Mat& depth_mm) {
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1, "MeasuredArea needs 16-bit depth");
  cv::Mat valid;
  cv::compare(depth_mm, 0, valid, cv::CMP_GT);  // 255 where measured
  cv::Mat per_column;
  cv::Mat per_row;
  cv::reduce(valid, per_column, 0, cv::REDUCE_SUM, CV_32S);
  cv::reduce(valid, per_row, 1, cv::REDUCE_SUM, CV_32S);
  constexpr double kMinShare = 0.05;
  // The first and one past the last index whose count reaches the share of `length` pixels.
  const auto span = [&](const cv::Mat& counts, int length) {
    const double min_sum = 255.0 * std::max(1.0, kMinShare * length);
    const int n = static_cast<int>(counts.total());
    int first = 0;
    while (first < n && counts.at<int>(first) < min_sum) ++first;
    int end = n;
    while (end > first && counts.at<int>(end - 1) < min_sum) --end;
    return std::make_pair(first, end);
  };
  const auto [left, right] = span(per_column, depth_mm.rows);
  const auto [top, bottom] = span(per_row, depth_mm.cols);
  if (left >= right || top >= bottom) return cv::Rect();
  return cv::Rect(left, top, right - left, bottom - top);
}

bool ClearSighting(uint16_t seen_mm, double point_z_m, double sighting_depth_m,
                   double sighting_max_m) {
  if (seen_mm == 0) return point_z_m <= sighting_max_m;
  return seen_mm * 1e-3 >= point_z_m - sighting_depth_m;
}

Eigen::Vector3d SurfaceNormal(const OcclusionCloud& cloud, const Eigen::Vector3d& world_point,
                              const VisibilityOptions& options) {
  const Eigen::Vector3f centre = world_point.cast<float>();
  const float radius = static_cast<float>(options.surface_radius_m);
  const std::vector<Eigen::Vector3f>& points = cloud.world_points;
  const auto begin =
      std::lower_bound(points.begin(), points.end(), centre.x() - radius,
                       [](const Eigen::Vector3f& voxel, float x) { return voxel.x() < x; });
  const auto end =
      std::upper_bound(begin, points.end(), centre.x() + radius,
                       [](float x, const Eigen::Vector3f& voxel) { return x < voxel.x(); });
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  int count = 0;
  for (auto it = begin; it != end; ++it) {
    const Eigen::Vector3f& voxel = *it;
    if ((voxel - centre).squaredNorm() > radius * radius) continue;
    const Eigen::Vector3d offset = (voxel - centre).cast<double>();
    sum += offset;
    sum_outer += offset * offset.transpose();
    ++count;
  }
  constexpr int kMinVoxels = 6;
  if (count < kMinVoxels) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d mean = sum / count;
  const Eigen::Matrix3d covariance = sum_outer / count - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  const Eigen::Vector3d spread = eigen.eigenvalues();  // ascending
  if (!(spread(0) <= options.max_surface_flatness * spread(1))) return Eigen::Vector3d::Zero();
  return eigen.eigenvectors().col(0).normalized();
}

LabelSightings SightLabels(const std::vector<store::LabelRecord>& labels,
                           const std::vector<SightingView>& views, const VisibilityOptions& options,
                           const OcclusionCloud* cloud) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const bool with_planes = cloud != nullptr && options.own_surface_m > 0.0;
  SIGHTMAP_CHECK(
      !with_planes || std::is_sorted(cloud->world_points.begin(), cloud->world_points.end(),
                                     [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
                                       return a.x() < b.x();
                                     }),
      "the occlusion cloud's points must be sorted by x");
  LabelSightings sightings(labels.size());
  for (size_t l = 0; l < labels.size(); ++l) {
    for (const store::LabelPoint& point : labels[l].points) {
      PointSighting sighting;
      for (const SightingView& view : views) {
        const std::optional<ViewedPoint> seen = PointInView(view, point.world);
        if (!seen || !ClearSighting(seen->seen_mm, seen->in_view.z(), options.sighting_depth_m,
                                    options.sighting_max_m)) {
          continue;
        }
        if (seen->seen_mm == 0 && !view.measured.empty() && !view.measured.contains(seen->pixel)) {
          continue;  // the band the sensor does not measure: nothing was seen through
        }
        // The ray from the keyframe to the point, in the world frame.
        sighting.mean_ray += view.cam_from_world.linear().transpose() * seen->in_view.normalized();
        ++sighting.keyframes;
      }
      if (sighting.keyframes > 0) sighting.mean_ray /= sighting.keyframes;
      if (with_planes) sighting.surface_normal = SurfaceNormal(*cloud, point.world, options);
      sightings[l].push_back(sighting);
    }
  }
  return sightings;
}

namespace {

// Whether points seen from a pose are hidden: behind the occlusion cloud's surface (a z-buffer
// drawn at the first question, so only when some label is in the view cone), or on the far side
// of what the keyframes saw from one side only.
class OcclusionTest {
 public:
  OcclusionTest(const OcclusionCloud* cloud, const Intrinsics& intrinsics,
                const Eigen::Isometry3d& world_from_cam, const VisibilityOptions& options)
      : cloud_(cloud),
        intrinsics_(intrinsics),
        world_from_cam_(world_from_cam),
        options_(options),
        cos_behind_(std::cos(DegToRad(options.behind_angle_deg))) {}

  bool Occluded(const Eigen::Vector3d& cam_point, const PointSighting* sighting,
                bool free_standing) {
    if (cloud_ == nullptr || cloud_->world_points.empty()) return false;
    const double surface = SurfaceDepth(cam_point);
    const double z = cam_point.z();
    const double margin = options_.margin_m + options_.margin_ratio * z;
    if (surface < z - margin && !OnOwnSurface(cam_point, surface, sighting)) return true;
    if (!SeenFromBehind(cam_point, sighting)) return false;
    const double behind_margin =
        free_standing ? options_.free_standing_behind_margin_m : options_.behind_margin_m;
    if (surface < z - behind_margin) return true;
    return options_.behind_needs_own_surface && std::isfinite(surface) && surface > z + margin;
  }

 private:
  // The z-buffer's depth at the point's pixel [m]; +infinity where the cloud shows nothing.
  double SurfaceDepth(const Eigen::Vector3d& cam_point) {
    if (zbuffer_.empty()) {
      const int ds = options_.zbuffer_downscale;
      small_ = intrinsics_.Scaled(std::max(1, (intrinsics_.width + ds - 1) / ds),
                                  std::max(1, (intrinsics_.height + ds - 1) / ds));
      zbuffer_ = RenderOcclusionDepth(*cloud_, small_, world_from_cam_, options_);
    }
    const Eigen::Vector2d pixel = small_.Project(cam_point);
    const int u = std::clamp(static_cast<int>(std::lround(pixel.x())), 0, small_.width - 1);
    const int v = std::clamp(static_cast<int>(std::lround(pixel.y())), 0, small_.height - 1);
    return zbuffer_.at<float>(v, u);
  }

  // Whether the z-buffer's surface on the line of sight, `surface` deep, lies within
  // own_surface_m of the plane the point sits on (so it is that plane, seen at a grazing angle).
  bool OnOwnSurface(const Eigen::Vector3d& cam_point, double surface,
                    const PointSighting* sighting) const {
    if (sighting == nullptr || options_.own_surface_m <= 0.0 || sighting->surface_normal.isZero()) {
      return false;
    }
    const Eigen::Vector3d normal = world_from_cam_.linear().transpose() * sighting->surface_normal;
    // The camera's distance from the plane; within own_surface_m it sees the plane edge-on and
    // cannot tell it from what stands on it.
    const double camera_off_plane = std::abs(normal.dot(cam_point));
    if (camera_off_plane <= options_.own_surface_m) return false;
    // The surface's point on the line of sight is cam_point x surface / z.
    return camera_off_plane * (1.0 - surface / cam_point.z()) <= options_.own_surface_m;
  }

  // Whether the photo looks at the point from the side the keyframes did not see it from (when
  // enough keyframes saw it, and mostly from one side).
  bool SeenFromBehind(const Eigen::Vector3d& cam_point, const PointSighting* sighting) const {
    if (sighting == nullptr || sighting->keyframes < options_.min_sighting_keyframes) return false;
    const double one_sidedness = sighting->mean_ray.norm();
    if (one_sidedness < options_.min_one_sidedness) return false;
    const Eigen::Vector3d photo_ray = world_from_cam_.linear() * cam_point.normalized();
    return photo_ray.dot(sighting->mean_ray) < cos_behind_ * one_sidedness;
  }

  const OcclusionCloud* cloud_;
  const Intrinsics& intrinsics_;
  const Eigen::Isometry3d& world_from_cam_;
  const VisibilityOptions& options_;
  const double cos_behind_;
  cv::Mat zbuffer_;
  Intrinsics small_;
};

// A label as the photo shows it: nothing when too few of its points lie in the image.
std::optional<ApplianceInView> LabelInView(const store::LabelRecord& label,
                                           const std::vector<PointSighting>* sightings,
                                           const Intrinsics& intrinsics,
                                           const Eigen::Isometry3d& cam_from_world,
                                           const VisibilityOptions& options,
                                           OcclusionTest* occlusion) {
  if (label.points.empty()) return std::nullopt;
  int in_view = 0;
  int unoccluded = 0;
  Eigen::Vector2d sum_visible = Eigen::Vector2d::Zero();
  Eigen::Vector2d sum_in_view = Eigen::Vector2d::Zero();
  double nearest = std::numeric_limits<double>::infinity();
  const bool free_standing = IsFreeStanding(label.type);
  for (size_t p = 0; p < label.points.size(); ++p) {
    const Eigen::Vector3d cam_point = cam_from_world * label.points[p].world;
    if (!(cam_point.z() > 0.0)) continue;
    const Eigen::Vector2d pixel = intrinsics.Project(cam_point);
    // Pixel centres at integers: the image spans [-0.5, size - 0.5).
    if (!(pixel.x() >= -0.5 && pixel.x() < intrinsics.width - 0.5 && pixel.y() >= -0.5 &&
          pixel.y() < intrinsics.height - 0.5)) {
      continue;
    }
    ++in_view;
    sum_in_view += pixel;
    nearest = std::min(nearest, cam_point.norm());
    if (!occlusion->Occluded(cam_point, sightings != nullptr ? &sightings->at(p) : nullptr,
                             free_standing)) {
      ++unoccluded;
      sum_visible += pixel;
    }
  }
  if (in_view == 0 ||
      in_view < options.min_in_view_share * static_cast<double>(label.points.size())) {
    return std::nullopt;
  }
  ApplianceInView appliance;
  appliance.name = label.name;
  appliance.type = label.type;
  appliance.distance_m = nearest;
  appliance.occluded = unoccluded < options.min_unoccluded_share * in_view;
  appliance.visible_share =
      static_cast<double>(unoccluded) / static_cast<double>(label.points.size());
  appliance.pixel =
      appliance.occluded || unoccluded == 0 ? sum_in_view / in_view : sum_visible / unoccluded;
  return appliance;
}

}  // namespace

bool IsFreeStanding(const std::string& type) {
  std::string words = type;
  for (char& c : words) {
    c = c == '_' || c == '-' ? ' ' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  std::istringstream in(words);
  std::string word;
  std::string last;
  while (in >> word) {
    if (word == "wall") return false;  // "wall lamp": hung on a wall, whatever it is
    last = word;
  }
  return last == "projector" || last == "lamp" || last == "monitor" || last == "printer";
}

std::vector<ApplianceInView> AppliancesInView(const std::vector<store::LabelRecord>& labels,
                                              const OcclusionCloud* cloud,
                                              const Intrinsics& intrinsics,
                                              const Eigen::Isometry3d& world_from_cam,
                                              const VisibilityOptions& options,
                                              const LabelSightings* sightings) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(sightings == nullptr || sightings->size() == labels.size(),
                 "one sighting list per label");
  std::vector<ApplianceInView> result;
  if (labels.empty()) return result;
  const Eigen::Isometry3d cam_from_world = world_from_cam.inverse();
  OcclusionTest occlusion(cloud, intrinsics, world_from_cam, options);
  for (size_t l = 0; l < labels.size(); ++l) {
    if (std::optional<ApplianceInView> appliance =
            LabelInView(labels[l], sightings != nullptr ? &(*sightings)[l] : nullptr, intrinsics,
                        cam_from_world, options, &occlusion)) {
      result.push_back(std::move(*appliance));
    }
  }
  std::stable_sort(result.begin(), result.end(),
                   [](const ApplianceInView& a, const ApplianceInView& b) {
                     return a.distance_m < b.distance_m;
                   });
  return result;
}

}  // namespace sightmap::identify
