#include "mapping/model_restore.h"

#include <map>
#include <memory>
#include <set>

#include "core/check.h"
#include "mapping/write_stage.h"

namespace sightmap::mapping {

RestoredModel RestoreModel(const store::Model& model, const Intrinsics& camera, bool load_color,
                           slam::Mapper* mapper, MapViewFeed* view) {
  SIGHTMAP_CHECK(mapper != nullptr && mapper->NumKeyframes() == 0,
                 "a model is restored into an empty mapper");
  RestoredModel restored;
  const std::vector<store::KeyframeInfo> stored = model.Keyframes();
  if (stored.empty()) return restored;
  const Intrinsics& first = stored.front().intrinsics;
  SIGHTMAP_CHECK(first.width == camera.width && first.height == camera.height,
                 "the model " << model.path() << " was mapped with a " << first.width << "x"
                              << first.height << " camera but the source delivers " << camera.width
                              << "x" << camera.height
                              << " — map into a new model or use the same camera mode");
  if (auto vocabulary = model.LoadVocabulary()) {
    SIGHTMAP_CHECK(vocabulary->first == slam::Vocabulary::kFormat,
                   "the model's vocabulary is of format '"
                       << vocabulary->first << "', this sightmap reads '"
                       << slam::Vocabulary::kFormat << "' — map into a new model");
    mapper->SetVocabulary(std::make_shared<const slam::Vocabulary>(
        slam::Vocabulary::Deserialize(vocabulary->second)));
    restored.vocabulary_restored = true;
  }

  std::map<int64_t, int64_t> mapper_id_of;  // model id -> mapper id
  for (const store::KeyframeInfo& info : stored) {
    const cv::Mat depth = model.LoadDepth(info.id);
    const cv::Mat color = load_color || view ? model.LoadColor(info.id) : cv::Mat();
    const int64_t id = mapper->RestoreKeyframe(info.timestamp_ns, model.LoadFeatures(info.id),
                                               depth, info.world_from_cam, color);
    SIGHTMAP_CHECK(id == static_cast<int64_t>(restored.store_ids.size()),
                   "the mapper restored keyframe " << info.id.value() << " as " << id);
    restored.store_ids.push_back(info.id);
    restored.last_timestamp_ns = info.timestamp_ns;
    mapper_id_of[info.id.value()] = id;
    if (view) {
      view->AddKeyframe(id, static_cast<int>(info.session.value()), info.world_from_cam, color,
                        depth, info.intrinsics);
    }
  }
  for (const store::LinkRecord& record : model.Links()) {
    slam::MapperLink link;
    link.from = mapper_id_of.at(record.from.value());
    link.to = mapper_id_of.at(record.to.value());
    link.to_in_from = record.to_in_from;
    link.information = record.information;
    link.type = record.type;
    link.active = record.active;
    mapper->RestoreLink(link);
    if (view && link.active && DrawnAsLoop(link.type)) {
      view->AddLoop(link.from, link.to);
    }
  }
  std::set<int> segments;
  for (int64_t id = 0; id < static_cast<int64_t>(restored.store_ids.size()); ++id) {
    if (segments.insert(mapper->SegmentOf(id)).second) restored.segment_members.push_back(id);
  }
  mapper->StartNewSegment();
  return restored;
}

RgbdFrame NewestKeyframeFrame(const store::Model& model, const RestoredModel& restored) {
  SIGHTMAP_CHECK(!restored.store_ids.empty(), "no keyframe was restored");
  RgbdFrame frame;
  frame.index = -1;
  frame.timestamp_ns = restored.last_timestamp_ns;
  frame.color = model.LoadColor(restored.store_ids.back());
  frame.depth = model.LoadDepth(restored.store_ids.back());
  return frame;
}

}  // namespace sightmap::mapping
