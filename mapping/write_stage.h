// The writing stage of `sightmap map`: what the mapping stage decided goes to the model on this
// stage's own thread, in order, each task in its own transaction: a keyframe with its links, every
// pose after an optimisation (with the stored links it switched off), the vocabulary once trained.
// A written keyframe then goes to the map view, which draws on its own thread and never blocks.
//
// The mapper numbers keyframes 0, 1, ... and the model numbers them its own way; this stage holds
// the one table between the two (restored keyframes first), since only it learns the model's ids.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "mapping/bounded_queue.h"
#include "mapping/map_view_feed.h"
#include "mapping/photo_features.h"
#include "slam/features.h"
#include "slam/mapper.h"
#include "store/model.h"

namespace sightmap::mapping {

// What the mapping stage hands the writer, in order.
struct WriteTask {
  enum class Kind { kKeyframe, kPoses, kVocabulary };
  Kind kind = Kind::kKeyframe;
  // kKeyframe: the record (links left empty) and its links with mapper ids at both ends (the new
  // keyframe's own id among them).
  int64_t mapper_id = -1;
  store::KeyframeRecord record;
  std::vector<slam::MapperLink> links;
  // Older links, stored already, whose measurement this keyframe revised (a bridged blind run):
  // replaced in the keyframe's transaction.
  std::vector<slam::MapperLink> revised;
  FeedStatus status;
  // kPoses: optimised poses by mapper id (ids not written yet are skipped), and stored links the
  // optimisation switched off or back on.
  std::vector<std::pair<int64_t, Eigen::Isometry3d>> poses;
  std::vector<slam::MapperLink> deactivated;
  std::vector<slam::MapperLink> reactivated;
  // kVocabulary: Vocabulary::Serialize()'s bytes.
  std::vector<uint8_t> vocabulary;
};

// Features for matching phone photos (RootSIFT), extracted from each keyframe's colour and depth
// on the writer's thread, so tracking and mapping keep their rate, and stored with it.
class WriteStage {
 public:
  // Starts the thread. `store_ids` maps the mapper ids of the keyframes already in the model
  // (restored, in mapper order) to their model ids; `session_number` (>= 1) colours the view's
  // track. `model` and `view` (may be null) must outlive the stage. With `photo_features`, each
  // keyframe is written with them. The thread runs `nice_increment` lower (Linux nice, per
  // thread, 0-19), as a replay's writer does: its work can wait for tracking and mapping's.
  WriteStage(store::Model* model, MapViewFeed* view, int session_number,
             std::vector<KeyframeId> store_ids, size_t queue_capacity,
             std::optional<PhotoFeatureExtraction> photo_features = std::nullopt,
             int nice_increment = 0);
  ~WriteStage();
  WriteStage(const WriteStage&) = delete;
  WriteStage& operator=(const WriteStage&) = delete;

  // Queues a task, waiting for room; false once the stage failed (the task is not written).
  bool Push(WriteTask task);
  // Writes what is queued and ends the thread (idempotent).
  void Finish();
  // The nice value the thread runs at, once it started (ThisThreadsNice() there).
  int thread_nice() const { return thread_nice_.load(); }

  // A write failed: the thread stopped and later tasks are refused (any thread).
  bool failed() const { return failed_.load(); }
  // The exception that stopped the stage; valid after Finish().
  std::exception_ptr error() const { return error_; }
  // Keyframes committed so far (any thread).
  int64_t committed() const { return committed_.load(); }

 private:
  void Run();
  void Write(WriteTask& task);
  void WriteKeyframe(WriteTask& task);
  void WritePoses(const WriteTask& task);
  KeyframeId StoreId(int64_t mapper_id) const;
  // A mapper link as the model stores it; an end at `new_keyframe` (not stored yet) is left unset.
  store::LinkRecord StoredLink(const slam::MapperLink& link, int64_t new_keyframe) const;

  store::Model* model_;
  MapViewFeed* view_;
  int session_number_;
  std::optional<PhotoFeatureExtraction> photo_features_;
  std::vector<KeyframeId> store_ids_;  // by mapper id; only the thread touches it once started
  BoundedQueue<WriteTask> tasks_;
  std::atomic<bool> failed_{false};
  std::atomic<int64_t> committed_{0};
  std::exception_ptr error_;  // written by the thread before it sets failed_
  const int nice_increment_;
  std::atomic<int> thread_nice_{-100};  // -100 until the thread started
  std::thread thread_;
};

}  // namespace sightmap::mapping
