// The keyframe-mapping stage of `sightmap map`: each keyframe the tracking stage emits goes through
// the Mapper (registration, loop closure, optimisation) on the session's own thread, and what
// changed becomes write tasks for the writing stage, in order: the keyframe with the links it
// made (stored with their state now, so a loop switched off in this very step is stored inactive),
// the poses an optimisation moved (every one, or the few a local one did) with the stored links it
// switched off, and the vocabulary once trained.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "mapping/model_restore.h"
#include "mapping/track_stage.h"
#include "mapping/write_stage.h"
#include "slam/mapper.h"
#include "slam/trajectory_eval.h"
#include "store/model.h"

namespace sightmap::mapping {

struct MapStageOptions {
  // A source with ground truth places a new model's first keyframe at its true pose, so the model
  // shares the scene's frame (see MappingOptions::anchor_to_ground_truth).
  bool anchor_to_ground_truth = true;
  // Keyframes take their ground-truth poses instead of being registered (an evaluation model).
  bool ground_truth_poses = false;
};

// "--ground-truth-poses needs a source with ground truth ...; <what> has none".
Error NoGroundTruthError(const std::string& what);

class MapStage {
 public:
  // `mapper` (holding the restored model, if any) must outlive the stage; `session` is the model's
  // id of the session the keyframes are written in.
  MapStage(slam::Mapper* mapper, SessionId session, const Intrinsics& camera,
           const MapStageOptions& options, const RestoredModel& restored);

  // Maps one keyframe and returns its write tasks (the keyframe's first). Throws what the mapper
  // throws, and NoGroundTruthError for a keyframe without ground truth when ground_truth_poses.
  std::vector<WriteTask> Map(KeyframeItem item);
  // Every pose as the mapper has it now.
  WriteTask AllPoses() const;
  // The session's last write: every part of the map optimised over all its links
  // (Mapper::OptimiseWhole), then every pose, with the stored links that optimisation switched
  // off. Keyframes mapped at their true poses (ground_truth_poses) are not moved.
  WriteTask Finish();

  int64_t keyframes() const { return static_cast<int64_t>(session_ids_.size()); }
  // A resumed session's keyframes reached a part of the stored map.
  bool joined_stored_map() const { return joined_; }
  // Mapping time of each keyframe [s].
  const std::vector<double>& keyframe_seconds() const { return keyframe_s_; }
  // Stored loop links an optimisation switched off later.
  int64_t links_rejected_after_commit() const { return links_rejected_after_commit_; }
  // Loop links switched off while mapping that the end's solve switched back on.
  int64_t links_reactivated_at_end() const { return links_reactivated_at_end_; }
  // Wall time of Finish's whole-map optimisation [s] (0 before it, or with ground_truth_poses).
  double final_optimisation_s() const { return final_optimisation_s_; }
  // This session's keyframes against their ground truth, when every one had it (and at least 3).
  std::optional<slam::TrajectoryError> Accuracy() const;

 private:
  slam::KeyframeReport AddToMapper(KeyframeItem& item);
  WriteTask PosesOf(const std::vector<int64_t>& ids) const;
  WriteTask KeyframeTask(const slam::KeyframeReport& report, RgbdFrame& frame,
                         std::vector<slam::MapperLink>* deactivated) const;

  slam::Mapper* mapper_;
  SessionId session_;
  Intrinsics camera_;
  MapStageOptions options_;
  std::vector<int64_t> restored_segment_members_;
  bool resumed_ = false;
  bool vocabulary_sent_ = false;
  bool joined_ = false;
  std::vector<int64_t> session_ids_;  // mapper ids of this session's keyframes
  std::vector<StampedPose> ground_truth_;
  std::vector<double> keyframe_s_;
  int64_t links_rejected_after_commit_ = 0;
  int64_t links_reactivated_at_end_ = 0;
  double final_optimisation_s_ = 0.0;
};

}  // namespace sightmap::mapping
