// The tracking stage of `sightmap map`: every frame the capture stage delivers goes through the
// Tracker on this stage's own thread, and the keyframes it decides go on to the mapping stage.
// Joined by bounded queues: a full keyframe queue makes the tracker wait (keyframes are never
// dropped), and the capture stage decides whether frames wait for the tracker (replays) or are
// dropped (a live sensor).
//
// Without tracking (a model of ground-truth poses, or tracking switched off) the stage hands every
// frame on as a keyframe: the capture stage picks one per period then, as the paper's 1 Hz capture
// did, so that a live sensor drops keyframes rather than frames; the mapper computes the features.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "core/camera.h"
#include "core/rgbd_frame.h"
#include "mapping/bounded_queue.h"
#include "slam/tracker.h"

namespace sightmap::mapping {

struct TrackStageOptions {
  // Track every frame (true), or hand every frame on as a keyframe (false).
  bool track = true;
  slam::TrackerOptions tracker;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const TrackStageOptions& options);
void from_json(const nlohmann::json& json, TrackStageOptions& options);

// A keyframe on its way to the mapper. Untracked keyframes carry only their frame.
struct KeyframeItem {
  slam::TrackedKeyframe keyframe;
  bool tracked = false;
};

// Per-frame tracking figures, for the summary and the benchmark.
struct TrackStageReport {
  slam::TrackerCounters counters;
  std::vector<double> frame_s;  // tracking time of each frame [s]
};

class TrackStage {
 public:
  // Starts the thread. `frames` is read until it ends; `keyframes` is closed when the stage ends
  // (the input ended, or an error: see error()). With `continue_from` (the newest stored keyframe
  // of a resumed replay) the tracker carries on from it (slam::Tracker::ContinueFrom).
  TrackStage(const Intrinsics& camera, const TrackStageOptions& options,
             BoundedQueue<RgbdFrame>* frames, BoundedQueue<KeyframeItem>* keyframes,
             std::optional<RgbdFrame> continue_from = std::nullopt);
  ~TrackStage();
  TrackStage(const TrackStage&) = delete;
  TrackStage& operator=(const TrackStage&) = delete;

  // Waits for the thread (after the input queue was closed).
  void Join();
  // The exception that ended the stage, or null.
  std::exception_ptr error() const;
  // Frames tracked so far (any thread).
  int64_t tracked_frames() const { return tracked_frames_.load(); }
  // Valid after Join().
  const TrackStageReport& report() const { return report_; }

 private:
  void Run();

  Intrinsics camera_;
  TrackStageOptions options_;
  std::optional<RgbdFrame> continue_from_;
  BoundedQueue<RgbdFrame>* frames_;
  BoundedQueue<KeyframeItem>* keyframes_;
  std::atomic<int64_t> tracked_frames_{0};
  TrackStageReport report_;
  mutable std::mutex error_mutex_;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace sightmap::mapping
