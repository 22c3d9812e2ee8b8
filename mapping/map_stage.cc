#include "mapping/map_stage.h"

#include <chrono>
#include <utility>

#include "core/check.h"

namespace sightmap::mapping {

Error NoGroundTruthError(const std::string& what) {
  return Error(
      "--ground-truth-poses needs a source with ground truth (the simulator, or a TUM folder with "
      "groundtruth.txt); " +
      what + " has none");
}

MapStage::MapStage(slam::Mapper* mapper, SessionId session, const Intrinsics& camera,
                   const MapStageOptions& options, const RestoredModel& restored)
    : mapper_(mapper),
      session_(session),
      camera_(camera),
      options_(options),
      restored_segment_members_(restored.segment_members),
      resumed_(!restored.store_ids.empty()),
      vocabulary_sent_(restored.vocabulary_restored) {
  SIGHTMAP_CHECK(mapper_ != nullptr, "the map stage needs a mapper");
}

slam::KeyframeReport MapStage::AddToMapper(KeyframeItem& item) {
  const RgbdFrame& frame = item.keyframe.frame;
  if (options_.ground_truth_poses && !frame.world_from_cam_gt) {
    throw NoGroundTruthError("the frame at " + std::to_string(frame.timestamp_ns) + " ns");
  }
  if (mapper_->NumKeyframes() == 0 && options_.anchor_to_ground_truth && frame.world_from_cam_gt) {
    mapper_->SetFirstPose(*frame.world_from_cam_gt);
  }
  if (options_.ground_truth_poses) {
    return mapper_->AddKeyframeAtPose(frame.timestamp_ns, frame.color, frame.depth,
                                      *frame.world_from_cam_gt);
  }
  // A copy: the images are shared, and the frame is written to the model afterwards.
  if (item.tracked) return mapper_->AddTrackedKeyframe(item.keyframe);
  return mapper_->AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
}

WriteTask MapStage::KeyframeTask(const slam::KeyframeReport& report, RgbdFrame& frame,
                                 std::vector<slam::MapperLink>* deactivated) const {
  WriteTask task;
  task.kind = WriteTask::Kind::kKeyframe;
  task.mapper_id = report.id;
  task.record.session = session_;
  task.record.timestamp_ns = frame.timestamp_ns;
  task.record.world_from_cam = report.world_from_cam;
  task.record.odom_world_from_cam = report.world_from_cam;
  task.record.intrinsics = camera_;
  task.record.color = std::move(frame.color);
  task.record.depth = std::move(frame.depth);
  task.record.features = mapper_->FeaturesOf(report.id);
  // This step's links are the newest of Links(). Older links it switched off were stored active
  // and are switched off with the poses; older links it revised are replaced with the keyframe.
  const std::vector<slam::MapperLink>& links = mapper_->Links();
  const size_t first_new = links.size() - report.new_links.size();
  for (size_t i = first_new; i < links.size(); ++i) task.links.push_back(links[i]);
  for (size_t index : report.rejected_links) {
    if (index < first_new) deactivated->push_back(links[index]);
  }
  for (size_t index : report.revised_links) {
    if (index < first_new) task.revised.push_back(links[index]);
  }
  return task;
}

std::vector<WriteTask> MapStage::Map(KeyframeItem item) {
  const slam::KeyframeReport report = AddToMapper(item);
  RgbdFrame& frame = item.keyframe.frame;
  keyframe_s_.push_back(report.times.total_s);
  session_ids_.push_back(report.id);
  if (frame.world_from_cam_gt)
    ground_truth_.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
  if (resumed_ && !joined_) {
    const int segment = mapper_->SegmentOf(report.id);
    for (int64_t member : restored_segment_members_) {
      joined_ = joined_ || mapper_->SegmentOf(member) == segment;
    }
  }

  std::vector<WriteTask> tasks;
  std::vector<slam::MapperLink> deactivated;
  tasks.push_back(KeyframeTask(report, frame, &deactivated));
  links_rejected_after_commit_ += static_cast<int64_t>(deactivated.size());
  if (report.optimised) {
    // A local optimisation moved a few keyframes: only those are written again.
    tasks.push_back(report.optimised_locally ? PosesOf(report.moved) : AllPoses());
    tasks.back().deactivated = std::move(deactivated);
  }
  if (!vocabulary_sent_ && mapper_->vocabulary()) {
    WriteTask vocabulary;
    vocabulary.kind = WriteTask::Kind::kVocabulary;
    vocabulary.vocabulary = mapper_->vocabulary()->Serialize();
    tasks.push_back(std::move(vocabulary));
    vocabulary_sent_ = true;
  }
  return tasks;
}

WriteTask MapStage::AllPoses() const {
  WriteTask poses;
  poses.kind = WriteTask::Kind::kPoses;
  const std::vector<StampedPose> trajectory = mapper_->Trajectory();
  poses.poses.reserve(trajectory.size());
  for (size_t id = 0; id < trajectory.size(); ++id) {
    poses.poses.emplace_back(static_cast<int64_t>(id), trajectory[id].world_from_cam);
  }
  return poses;
}

WriteTask MapStage::Finish() {
  std::vector<slam::MapperLink> deactivated;
  std::vector<slam::MapperLink> reactivated;
  if (!options_.ground_truth_poses && mapper_->NumKeyframes() > 0) {
    const auto start = std::chrono::steady_clock::now();
    const slam::KeyframeReport report = mapper_->OptimiseWhole();
    final_optimisation_s_ =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (size_t index : report.rejected_links) deactivated.push_back(mapper_->Links()[index]);
    for (size_t index : report.reactivated_links) reactivated.push_back(mapper_->Links()[index]);
    links_rejected_after_commit_ += static_cast<int64_t>(deactivated.size());
    links_reactivated_at_end_ = static_cast<int64_t>(reactivated.size());
  }
  WriteTask poses = AllPoses();
  poses.deactivated = std::move(deactivated);
  poses.reactivated = std::move(reactivated);
  return poses;
}

WriteTask MapStage::PosesOf(const std::vector<int64_t>& ids) const {
  WriteTask poses;
  poses.kind = WriteTask::Kind::kPoses;
  poses.poses.reserve(ids.size());
  for (int64_t id : ids) poses.poses.emplace_back(id, mapper_->WorldFromCam(id));
  return poses;
}

std::optional<slam::TrajectoryError> MapStage::Accuracy() const {
  if (ground_truth_.size() < 3 || ground_truth_.size() != session_ids_.size()) return std::nullopt;
  std::vector<StampedPose> estimate;
  estimate.reserve(session_ids_.size());
  for (size_t i = 0; i < session_ids_.size(); ++i) {
    estimate.push_back({ground_truth_[i].timestamp_ns, mapper_->WorldFromCam(session_ids_[i])});
  }
  try {
    return slam::EvaluateTrajectory(ground_truth_, estimate);
  } catch (const sightmap::Error&) {
    return std::nullopt;  // too few poses to align
  }
}

}  // namespace sightmap::mapping
