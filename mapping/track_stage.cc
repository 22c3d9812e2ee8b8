#include "mapping/track_stage.h"

#include <utility>

#include "core/check.h"
#include "core/options_json.h"

namespace sightmap::mapping {

bool TrackStageOptions::Check(std::string* error) const { return tracker.Check(error); }

TrackStage::TrackStage(const Intrinsics& camera, const TrackStageOptions& options,
                       BoundedQueue<RgbdFrame>* frames, BoundedQueue<KeyframeItem>* keyframes,
                       std::optional<RgbdFrame> continue_from)
    : camera_(camera),
      options_(options),
      continue_from_(std::move(continue_from)),
      frames_(frames),
      keyframes_(keyframes) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  SIGHTMAP_CHECK(frames_ != nullptr && keyframes_ != nullptr, "the track stage needs its queues");
  thread_ = std::thread([this] { Run(); });
}

TrackStage::~TrackStage() {
  // The queues outlive the stage; closing the input lets the thread end.
  frames_->Close();
  Join();
}

void TrackStage::Join() {
  if (thread_.joinable()) thread_.join();
}

std::exception_ptr TrackStage::error() const {
  std::lock_guard<std::mutex> lock(error_mutex_);
  return error_;
}

void TrackStage::Run() {
  try {
    if (options_.track) {
      slam::Tracker tracker(camera_, options_.tracker);
      if (continue_from_) tracker.ContinueFrom(*continue_from_);
      bool taken = true;
      while (taken) {
        std::optional<RgbdFrame> frame = frames_->Pop();
        if (!frame) break;
        slam::TrackResult result = tracker.Track(*frame);
        report_.frame_s.push_back(result.total_s);
        ++tracked_frames_;
        for (slam::TrackedKeyframe& keyframe : result.keyframes) {
          taken = taken && keyframes_->Push(KeyframeItem{std::move(keyframe), true});
        }
        // A closed keyframe queue: the mapping stage stopped taking keyframes, also while this
        // frame made none (the tracker may be waiting for a frame to start the map on).
        taken = taken && !keyframes_->closed();
      }
      // A stream that ended before a frame could anchor the map still gives its richest frame.
      for (slam::TrackedKeyframe& keyframe : tracker.Finish().keyframes) {
        if (taken) taken = keyframes_->Push(KeyframeItem{std::move(keyframe), true});
      }
      report_.counters = tracker.counters();
    } else {
      while (std::optional<RgbdFrame> frame = frames_->Pop()) {
        KeyframeItem item;
        item.keyframe.frame = std::move(*frame);
        if (!keyframes_->Push(std::move(item))) break;
        ++report_.counters.keyframes;
      }
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(error_mutex_);
    error_ = std::current_exception();
    frames_->Close();
  }
  keyframes_->Close();
}

SIGHTMAP_OPTIONS_JSON(TrackStageOptions, track, tracker)

}  // namespace sightmap::mapping
