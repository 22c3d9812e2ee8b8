#include "render/map_scene.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::render {

bool KeyframeCloudOptions::Check(std::string* error) const {
  if (!(voxel_m > 0.0)) {
    *error = "voxel_m must be positive";
    return false;
  }
  if (!(min_depth_m >= 0.0 && max_depth_m > min_depth_m)) {
    *error = "need 0 <= min_depth_m < max_depth_m";
    return false;
  }
  if (pixel_step < 1) {
    *error = "pixel_step must be at least 1";
    return false;
  }
  return true;
}

MapKeyframe FromRgbd(const cv::Mat& bgr, const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                     const KeyframeCloudOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::string error;
  SIGHTMAP_CHECK(intrinsics.Check(&error), "invalid intrinsics: " << error);
  SIGHTMAP_CHECK(
      bgr.type() == CV_8UC3 && depth_mm.type() == CV_16UC1 && bgr.size() == depth_mm.size(),
      "FromRgbd needs a BGR image and a 16-bit depth image [mm] of the same size");
  SIGHTMAP_CHECK(bgr.cols == intrinsics.width && bgr.rows == intrinsics.height,
                 "image size " << bgr.cols << "x" << bgr.rows << " differs from the intrinsics' "
                               << intrinsics.width << "x" << intrinsics.height);
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Vector3i color_sum = Eigen::Vector3i::Zero();  // RGB
    int count = 0;
  };
  std::unordered_map<uint64_t, Voxel> voxels;
  voxels.reserve(static_cast<size_t>(bgr.total()) / 16);
  const double inv_voxel = 1.0 / options.voxel_m;
  const uint16_t min_mm = static_cast<uint16_t>(std::ceil(options.min_depth_m * 1000.0));
  const uint16_t max_mm =
      static_cast<uint16_t>(std::min(65535.0, std::floor(options.max_depth_m * 1000.0)));
  // 21 bits per axis, offset so negative coordinates pack too.
  auto key_of = [](int64_t x, int64_t y, int64_t z) {
    constexpr int64_t kOffset = 1 << 20;
    constexpr uint64_t kMask = (1u << 21) - 1;
    return (static_cast<uint64_t>(x + kOffset) & kMask) |
           ((static_cast<uint64_t>(y + kOffset) & kMask) << 21) |
           ((static_cast<uint64_t>(z + kOffset) & kMask) << 42);
  };
  for (int v = 0; v < depth_mm.rows; v += options.pixel_step) {
    const uint16_t* depth_row = depth_mm.ptr<uint16_t>(v);
    const cv::Vec3b* color_row = bgr.ptr<cv::Vec3b>(v);
    for (int u = 0; u < depth_mm.cols; u += options.pixel_step) {
      const uint16_t mm = depth_row[u];
      if (mm == 0 || mm < min_mm || mm > max_mm) continue;
      const Eigen::Vector3d p = intrinsics.Unproject(u, v, mm * 1e-3);
      const uint64_t key = key_of(static_cast<int64_t>(std::floor(p.x() * inv_voxel)),
                                  static_cast<int64_t>(std::floor(p.y() * inv_voxel)),
                                  static_cast<int64_t>(std::floor(p.z() * inv_voxel)));
      Voxel& voxel = voxels[key];
      voxel.sum += p;
      const cv::Vec3b& c = color_row[u];
      voxel.color_sum += Eigen::Vector3i(c[2], c[1], c[0]);
      ++voxel.count;
    }
  }
  MapKeyframe keyframe;
  keyframe.points_cam.reserve(voxels.size());
  keyframe.colors.reserve(voxels.size());
  for (const auto& [key, voxel] : voxels) {
    keyframe.points_cam.push_back((voxel.sum / voxel.count).cast<float>());
    const Eigen::Vector3i c = voxel.color_sum / voxel.count;
    keyframe.colors.push_back(
        {static_cast<uint8_t>(c.x()), static_cast<uint8_t>(c.y()), static_cast<uint8_t>(c.z())});
  }
  return keyframe;
}

void MapUpdate::Merge(MapUpdate&& later) {
  keyframes.insert(keyframes.end(), std::make_move_iterator(later.keyframes.begin()),
                   std::make_move_iterator(later.keyframes.end()));
  // Poses coalesce per keyframe (the last one wins), so a slow consumer facing an optimiser that
  // re-sends every pose after each loop closure holds one pose per keyframe, not one per round.
  // A pose for a keyframe earlier in `keyframes` would be applied after it anyway: same result.
  if (!later.poses.empty()) {
    std::unordered_map<int64_t, size_t> index;
    index.reserve(poses.size());
    for (size_t i = 0; i < poses.size(); ++i) index[poses[i].id] = i;
    for (PoseUpdate& pose : later.poses) {
      const auto it = index.find(pose.id);
      if (it != index.end()) {
        poses[it->second] = pose;
      } else {
        index[pose.id] = poses.size();
        poses.push_back(pose);
      }
    }
  }
  // A removal of a loop this batch adds cancels that addition: removing it when applied (before
  // the additions) would find it absent, or take an older copy of it instead.
  for (const LoopEdge& removed : later.removed_loops) {
    const auto added = std::find(loops.begin(), loops.end(), removed);
    if (added != loops.end()) {
      loops.erase(added);
    } else {
      removed_loops.push_back(removed);
    }
  }
  loops.insert(loops.end(), later.loops.begin(), later.loops.end());
  sightings.insert(sightings.end(), later.sightings.begin(), later.sightings.end());
  if (later.camera) camera = later.camera;
  if (later.appliances) appliances = std::move(later.appliances);
  if (later.status) status = later.status;
}

bool MapUpdate::empty() const {
  return keyframes.empty() && poses.empty() && loops.empty() && removed_loops.empty() &&
         sightings.empty() && !camera && !appliances && !status;
}

MapScene::MapScene(const Eigen::Vector3d& world_up) : world_up_(world_up) {
  SIGHTMAP_CHECK(world_up.norm() > 0.5, "world_up must be a non-zero direction");
  world_up_.normalize();
  FloorAxes(world_up_, &floor_x_, &floor_y_);
}

bool SectorOptions::Check(std::string* error) const {
  if (sectors < 1 || sectors > 64) {
    *error = "sectors must be in [1, 64]";
    return false;
  }
  if (!(min_distance_m >= 0.0 && max_distance_m > min_distance_m)) {
    *error = "the sectors' distance band needs 0 <= min_distance_m < max_distance_m";
    return false;
  }
  return true;
}

Eigen::Vector3d MapScene::FloorDirection(double bearing_deg) const {
  const double a = DegToRad(bearing_deg);
  return std::cos(a) * floor_x_ + std::sin(a) * floor_y_;
}

std::vector<uint64_t> MapScene::SeenSectors(const SectorOptions& options) const {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::vector<uint64_t> seen(appliances_.size(), 0);
  for (const LabelSighting& sighting : sightings_) {
    const auto keyframe = keyframes_.find(sighting.keyframe_id);
    if (keyframe == keyframes_.end() || sighting.appliance < 0 ||
        sighting.appliance >= static_cast<int>(appliances_.size())) {
      continue;
    }
    const Eigen::Vector3d offset = keyframe->second.world_from_cam.translation() -
                                   appliances_[static_cast<size_t>(sighting.appliance)].world_point;
    const double distance = offset.norm();
    if (distance < options.min_distance_m || distance > options.max_distance_m) continue;
    const double bearing = FloorBearingDeg(offset, floor_x_, floor_y_);
    const int sector =
        std::min(options.sectors - 1, static_cast<int>(bearing * options.sectors / 360.0));
    seen[static_cast<size_t>(sighting.appliance)] |= uint64_t{1} << sector;
  }
  return seen;
}

void MapScene::Apply(MapUpdate&& update) {
  for (MapKeyframe& keyframe : update.keyframes) {
    SIGHTMAP_CHECK(keyframe.colors.size() == keyframe.points_cam.size(),
                   "keyframe " << keyframe.id << " has " << keyframe.points_cam.size()
                               << " points but " << keyframe.colors.size() << " colours");
    auto it = keyframes_.find(keyframe.id);
    if (it != keyframes_.end()) {
      num_points_ -= it->second.points_cam.size();
      it->second = std::move(keyframe);
    } else {
      it = keyframes_.emplace(keyframe.id, std::move(keyframe)).first;
    }
    num_points_ += it->second.points_cam.size();
    points_versions_[it->first] = next_version_++;
  }
  for (const PoseUpdate& pose : update.poses) {
    const auto it = keyframes_.find(pose.id);
    if (it != keyframes_.end()) it->second.world_from_cam = pose.world_from_cam;
  }
  for (const LoopEdge& removed : update.removed_loops) {
    const auto it = std::find(loops_.begin(), loops_.end(), removed);
    if (it != loops_.end()) loops_.erase(it);
  }
  loops_.insert(loops_.end(), update.loops.begin(), update.loops.end());
  sightings_.insert(sightings_.end(), update.sightings.begin(), update.sightings.end());
  if (update.camera) camera_ = update.camera;
  if (update.appliances) appliances_ = std::move(*update.appliances);
  if (update.status) status_ = update.status;
}

uint64_t MapScene::points_version(int64_t id) const {
  const auto it = points_versions_.find(id);
  return it == points_versions_.end() ? 0 : it->second;
}

MapStatus MapScene::status() const {
  if (status_) return *status_;
  MapStatus status;
  status.keyframes = static_cast<int64_t>(keyframes_.size());
  status.loops = static_cast<int64_t>(loops_.size());
  return status;
}

std::vector<Eigen::Vector3d> MapScene::ExtentSample(size_t per_keyframe) const {
  std::vector<Eigen::Vector3d> sample;
  for (const auto& [id, keyframe] : keyframes_) {
    sample.push_back(keyframe.world_from_cam.translation());
    const size_t n = keyframe.points_cam.size();
    if (n == 0 || per_keyframe == 0) continue;
    const size_t step = std::max<size_t>(1, n / per_keyframe);
    for (size_t i = 0; i < n; i += step) {
      sample.push_back(keyframe.world_from_cam * keyframe.points_cam[i].cast<double>());
    }
  }
  if (camera_) sample.push_back(camera_->translation());
  for (const ApplianceLabel& label : appliances_) sample.push_back(label.world_point);
  return sample;
}

Eigen::Vector3f SessionColor(int session) {
  // Distinct on a dark background and unlike the red/green/yellow tracking colours.
  static const Eigen::Vector3f kPalette[] = {
      {0.20f, 0.65f, 1.00f},  // blue
      {1.00f, 0.55f, 0.10f},  // orange
      {0.75f, 0.40f, 1.00f},  // violet
      {0.10f, 0.90f, 0.85f},  // cyan
      {1.00f, 0.45f, 0.75f},  // pink
      {0.65f, 0.85f, 0.25f},  // olive
  };
  constexpr int kCount = static_cast<int>(sizeof(kPalette) / sizeof(kPalette[0]));
  const int index = ((session - 1) % kCount + kCount) % kCount;
  return kPalette[index];
}

}  // namespace sightmap::render
