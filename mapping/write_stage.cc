#include "mapping/write_stage.h"

#include <optional>

#include "core/check.h"
#include "core/thread_priority.h"

namespace sightmap::mapping {

WriteStage::WriteStage(store::Model* model, MapViewFeed* view, int session_number,
                       std::vector<KeyframeId> store_ids, size_t queue_capacity,
                       std::optional<PhotoFeatureExtraction> photo_features, int nice_increment)
    : model_(model),
      view_(view),
      session_number_(session_number),
      photo_features_(std::move(photo_features)),
      store_ids_(std::move(store_ids)),
      tasks_(queue_capacity),
      nice_increment_(nice_increment) {
  SIGHTMAP_CHECK(model_ != nullptr, "the write stage needs a model");
  SIGHTMAP_CHECK(nice_increment_ >= 0 && nice_increment_ <= 19,
                 "the writer's nice increment must be in [0, 19], not " << nice_increment_);
  SIGHTMAP_CHECK(session_number_ >= 1, "session numbers start at 1, not " << session_number_);
  if (photo_features_) SIGHTMAP_CHECK_OPTIONS(*photo_features_);
  thread_ = std::thread([this] { Run(); });
}

WriteStage::~WriteStage() { Finish(); }

bool WriteStage::Push(WriteTask task) { return !failed_ && tasks_.Push(std::move(task)); }

void WriteStage::Finish() {
  tasks_.Close();
  if (thread_.joinable()) thread_.join();
}

void WriteStage::Run() {
  if (nice_increment_ > 0) (void)LowerThisThreadsPriority(nice_increment_);
  thread_nice_ = ThisThreadsNice();
  try {
    while (std::optional<WriteTask> task = tasks_.Pop()) Write(*task);
  } catch (...) {
    error_ = std::current_exception();
    failed_ = true;
    // Whoever waits for room is let go; what is queued is not written.
    tasks_.Close();
    tasks_.Clear();
  }
}

void WriteStage::Write(WriteTask& task) {
  switch (task.kind) {
    case WriteTask::Kind::kKeyframe:
      WriteKeyframe(task);
      break;
    case WriteTask::Kind::kPoses:
      WritePoses(task);
      break;
    case WriteTask::Kind::kVocabulary:
      model_->SetVocabulary(slam::Vocabulary::kFormat, task.vocabulary);
      break;
  }
}

KeyframeId WriteStage::StoreId(int64_t mapper_id) const {
  SIGHTMAP_CHECK(mapper_id >= 0 && mapper_id < static_cast<int64_t>(store_ids_.size()),
                 "keyframe " << mapper_id << " is not in the model yet");
  return store_ids_[static_cast<size_t>(mapper_id)];
}

store::LinkRecord WriteStage::StoredLink(const slam::MapperLink& link, int64_t new_keyframe) const {
  store::LinkRecord stored;
  // The new keyframe's own end is left unset: the model fills in the id it gives it.
  stored.from = link.from == new_keyframe ? KeyframeId() : StoreId(link.from);
  stored.to = link.to == new_keyframe ? KeyframeId() : StoreId(link.to);
  stored.type = link.type;
  stored.to_in_from = link.to_in_from;
  stored.information = link.information;
  stored.active = link.active;
  return stored;
}

void WriteStage::WriteKeyframe(WriteTask& task) {
  SIGHTMAP_CHECK(task.mapper_id == static_cast<int64_t>(store_ids_.size()),
                 "keyframe " << task.mapper_id << " reached the writer out of order (expected "
                             << store_ids_.size() << ")");
  store::KeyframeRecord& record = task.record;
  for (const slam::MapperLink& link : task.links) {
    record.links.push_back(StoredLink(link, task.mapper_id));
  }
  for (const slam::MapperLink& link : task.revised) {
    record.revised_links.push_back(StoredLink(link, task.mapper_id));
  }
  if (photo_features_ && !record.photo_features) {
    // Only features with a 3D point: a photo is matched to points, the rest would be stored for
    // nothing.
    record.photo_features =
        ExtractPhotoFeatures(record.color, record.depth, record.intrinsics, *photo_features_);
  }
  store_ids_.push_back(model_->AddKeyframe(record));
  ++committed_;
  if (!view_) return;
  view_->AddKeyframe(task.mapper_id, session_number_, record.world_from_cam, record.color,
                     record.depth, record.intrinsics);
  for (const slam::MapperLink& link : task.links) {
    if (link.active && DrawnAsLoop(link.type)) view_->AddLoop(link.from, link.to);
  }
  view_->SetCamera(record.world_from_cam);
  view_->SetStatus(task.status);
}

void WriteStage::WritePoses(const WriteTask& task) {
  std::vector<std::pair<KeyframeId, Eigen::Isometry3d>> poses;
  poses.reserve(task.poses.size());
  for (const auto& [id, pose] : task.poses) {
    if (id >= 0 && id < static_cast<int64_t>(store_ids_.size())) {
      poses.emplace_back(store_ids_[static_cast<size_t>(id)], pose);
    }
  }
  const auto keys_of = [this](const std::vector<slam::MapperLink>& links) {
    std::vector<store::LinkKey> keys;
    for (const slam::MapperLink& link : links) {
      keys.push_back({StoreId(link.from), StoreId(link.to), link.type});
    }
    return keys;
  };
  model_->UpdateGraph(poses, keys_of(task.deactivated), keys_of(task.reactivated));
  if (!view_) return;
  view_->UpdatePoses(task.poses);
  // The view draws what the model holds: a loop switched off leaves the map, one switched back on
  // (the end's solve judging again) returns.
  for (const slam::MapperLink& link : task.deactivated) {
    if (DrawnAsLoop(link.type)) view_->RemoveLoop(link.from, link.to);
  }
  for (const slam::MapperLink& link : task.reactivated) {
    if (DrawnAsLoop(link.type)) view_->AddLoop(link.from, link.to);
  }
}

}  // namespace sightmap::mapping
