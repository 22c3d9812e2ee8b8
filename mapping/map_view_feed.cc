#include "mapping/map_view_feed.h"

#include <algorithm>

#include "core/check.h"
#include "core/options_json.h"
#include "identify/labels.h"
#include "render/map_scene.h"
#include "render/map_view_factory.h"

namespace sightmap::mapping {
namespace {

render::ViewMode ToRender(ViewChoice choice) {
  switch (choice) {
    case ViewChoice::kAuto:
      return render::ViewMode::kAuto;
    case ViewChoice::kPreview:
      return render::ViewMode::kPreview;
    case ViewChoice::kHeadless:
      return render::ViewMode::kHeadless;
  }
  return render::ViewMode::kAuto;
}

}  // namespace

bool DrawnAsLoop(LinkType type) { return type != LinkType::kOdometry && type != LinkType::kPrior; }

bool MapViewFeedOptions::Check(std::string* error) const {
  if (progress_every_n_keyframes < 1) {
    *error = "progress_every_n_keyframes must be >= 1";
    return false;
  }
  if (cloud_pixel_step < 1 || !(cloud_voxel_m > 0.0)) {
    *error = "cloud_pixel_step must be >= 1 and cloud_voxel_m > 0";
    return false;
  }
  if (!(world_up.norm() > 0.0)) {
    *error = "world_up must not be zero";
    return false;
  }
  return true;
}

struct MapViewFeed::Impl {
  MapViewFeedOptions options;
  std::unique_ptr<render::MapView> view;
  render::KeyframeCloudOptions cloud;
  std::vector<store::LabelRecord> labels;
};

std::unique_ptr<MapViewFeed> MapViewFeed::Create(const MapViewFeedOptions& options,
                                                 std::ostream* notices) {
  SIGHTMAP_CHECK_OPTIONS(options);
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->cloud.pixel_step = options.cloud_pixel_step;
  impl->cloud.voxel_m = options.cloud_voxel_m;
  render::MapViewOptions view;
  view.mode = ToRender(options.choice);
  view.progress.png_path = options.progress_png;
  view.progress.every_n_keyframes = options.progress_every_n_keyframes;
  view.progress.world_up = options.world_up.normalized();
  view.preview.world_up = options.world_up.normalized();
  view.preview.title = "sightmap map";
  impl->view = render::CreateMapView(view, notices);
  return std::unique_ptr<MapViewFeed>(new MapViewFeed(std::move(impl)));
}

MapViewFeed::MapViewFeed(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapViewFeed::~MapViewFeed() = default;

void MapViewFeed::AddKeyframe(int64_t id, int session, const Eigen::Isometry3d& world_from_cam,
                              const cv::Mat& bgr, const cv::Mat& depth_mm,
                              const Intrinsics& intrinsics) {
  render::MapKeyframe keyframe = render::FromRgbd(bgr, depth_mm, intrinsics, impl_->cloud);
  keyframe.id = id;
  keyframe.session = std::max(1, session);
  keyframe.world_from_cam = world_from_cam;
  render::MapUpdate update;
  update.keyframes.push_back(std::move(keyframe));
  if (!impl_->labels.empty() && !depth_mm.empty()) {
    store::KeyframeInfo info;
    info.world_from_cam = world_from_cam;
    info.intrinsics = intrinsics;
    for (const identify::LabelInKeyframe& in_view :
         identify::LabelsInKeyframe(info, depth_mm, impl_->labels)) {
      const bool visible =
          std::any_of(in_view.points.begin(), in_view.points.end(),
                      [](const identify::LabelPointInKeyframe& point) { return !point.hidden; });
      if (!visible) continue;
      update.sightings.push_back({id, static_cast<int>(in_view.label - impl_->labels.data())});
    }
  }
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::SetLabels(const std::vector<store::LabelRecord>& labels) {
  impl_->labels.clear();
  std::vector<render::ApplianceLabel> appliances;
  for (const store::LabelRecord& label : labels) {
    if (label.points.empty()) continue;
    appliances.push_back({label.name, identify::LabelCentre(label)});
    impl_->labels.push_back(label);
  }
  render::MapUpdate update;
  update.appliances = std::move(appliances);
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::UpdatePoses(
    const std::vector<std::pair<int64_t, Eigen::Isometry3d>>& world_from_cam) {
  render::MapUpdate update;
  update.poses.reserve(world_from_cam.size());
  for (const auto& [id, pose] : world_from_cam) update.poses.push_back({id, pose});
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::AddLoop(int64_t from_id, int64_t to_id) {
  render::MapUpdate update;
  update.loops.push_back({from_id, to_id});
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::RemoveLoop(int64_t from_id, int64_t to_id) {
  render::MapUpdate update;
  update.removed_loops.push_back({from_id, to_id});
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::SetCamera(const Eigen::Isometry3d& world_from_cam) {
  render::MapUpdate update;
  update.camera = world_from_cam;
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::SetStatus(const FeedStatus& status) {
  render::MapUpdate update;
  update.status = render::MapStatus{status.keyframes, status.loops, status.tracking,
                                    status.keyframes_per_s, status.elapsed_s};
  impl_->view->Submit(std::move(update));
}

void MapViewFeed::SetLiveImages(const cv::Mat& bgr, const cv::Mat& depth_mm) {
  impl_->view->SetLiveImages(bgr, depth_mm);
}

bool MapViewFeed::paused() const { return impl_->view->paused(); }
bool MapViewFeed::stop_requested() const { return impl_->view->stop_requested(); }
void MapViewFeed::Finish() { impl_->view->Finish(); }
std::string MapViewFeed::description() const { return impl_->view->description(); }

namespace {
const std::pair<ViewChoice, const char*> kViewChoiceNames[] = {{ViewChoice::kAuto, "auto"},
                                                               {ViewChoice::kPreview, "preview"},
                                                               {ViewChoice::kHeadless, "headless"}};
}  // namespace

void to_json(nlohmann::json& json, const ViewChoice& choice) {
  options_json::WriteEnum(json, choice, kViewChoiceNames);
}
void from_json(const nlohmann::json& json, ViewChoice& choice) {
  options_json::ReadEnum(json, choice, kViewChoiceNames);
}

SIGHTMAP_OPTIONS_JSON(MapViewFeedOptions, choice, progress_png, progress_every_n_keyframes,
                      world_up, cloud_pixel_step, cloud_voxel_m)

}  // namespace sightmap::mapping
