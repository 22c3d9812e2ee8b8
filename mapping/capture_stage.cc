#include "mapping/capture_stage.h"

#include <chrono>
#include <exception>
#include <utility>

#include "core/check.h"
#include "core/thread_priority.h"

namespace sightmap::mapping {

using Clock = std::chrono::steady_clock;

bool CaptureStageOptions::Check(std::string* error) const {
  if (start_frame < 0) {
    *error = "start_frame must be >= 0";
    return false;
  }
  if (take_every < 1) {
    *error = "take_every must be >= 1";
    return false;
  }
  if (replay_nice_increment < 0 || replay_nice_increment > 19) {
    *error = "replay_nice_increment must be in [0, 19]";
    return false;
  }
  return sampler.Check(error);
}

CaptureStage::CaptureStage(capture::RgbdSource* source, const CaptureStageOptions& options,
                           BoundedQueue<RgbdFrame>* frames, MapViewFeed* view)
    : source_(source), options_(options), frames_(frames), view_(view), sampler_(options.sampler) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  SIGHTMAP_CHECK(source_ != nullptr && frames_ != nullptr,
                 "the capture stage needs a source and a frame queue");
  thread_ = std::thread([this] { Run(); });
}

CaptureStage::~CaptureStage() {
  Stop();
  Join();
}

void CaptureStage::Stop() {
  stop_ = true;
  frames_->Close();
  frames_->Clear();
}

void CaptureStage::Join() {
  if (thread_.joinable()) thread_.join();
}

bool CaptureStage::BeforeStart(int64_t index, TimestampNs timestamp_ns) const {
  return index < options_.start_frame ||
         (options_.after_timestamp_ns && timestamp_ns <= *options_.after_timestamp_ns);
}

void CaptureStage::SkipCheaply() {
  for (std::optional<capture::RgbdSource::FrameStamp> stamp = source_->PeekStamp();
       !stop_ && stamp && BeforeStart(stamp->index, stamp->timestamp_ns);
       stamp = source_->PeekStamp()) {
    source_->SkipNext();
    ++frames_read_;
    ++frames_skipped_;
  }
}

bool CaptureStage::Wanted(const RgbdFrame& frame) {
  if (options_.sample_keyframes) return sampler_.Accept(frame.timestamp_ns);
  return (frame.index - options_.start_frame) % options_.take_every == 0;
}

bool CaptureStage::WaitWhilePaused() {
  if (!view_ || !view_->paused()) return true;
  if (options_.live) return false;
  while (view_->paused() && !stop_ && !view_->stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

void CaptureStage::NoteSourceStats() {
  const capture::SourceStats stats = source_->stats();
  source_missed_ = stats.missed_depth_frames;
  unpaired_ = stats.unpaired_frames;
}

void CaptureStage::Run() {
  // Best effort: refused, the replay competes at normal priority (tracking's latency suffers).
  if (!options_.live) (void)LowerThisThreadsPriority(options_.replay_nice_increment);
  try {
    SkipCheaply();
    Clock::time_point last_live_image = Clock::now() - std::chrono::seconds(1);
    while (!stop_) {
      std::optional<RgbdFrame> frame = source_->Next();
      NoteSourceStats();
      if (!frame) break;
      // Mesa's llvmpipe rasterises on threads it starts with the process's first GL context, at
      // the priority of the thread that made it: the simulator's rendering is this replay's
      // capture work, so they run at its priority too (the main command on the 2-core Zen 3:
      // keyframe p95 167-171 -> 140 ms, tracking p95 45 -> 37 ms, wall time and map the same).
      // Where there is no GPU a replay's preview window draws through llvmpipe too, and waits
      // with them.
      if (frames_read_ == 0 && !options_.live) {
        (void)LowerThreadsNamed("llvmpipe-", ThisThreadsNice());
      }
      ++frames_read_;
      if (BeforeStart(frame->index, frame->timestamp_ns)) {
        ++frames_skipped_;
        continue;
      }
      if (view_ && Clock::now() - last_live_image > std::chrono::milliseconds(100)) {
        view_->SetLiveImages(frame->color, frame->depth);
        last_live_image = Clock::now();
      }
      if (!WaitWhilePaused() || !Wanted(*frame)) continue;
      if (options_.live) {
        const auto pushed = frames_->PushNewest(std::move(*frame));
        if (pushed == BoundedQueue<RgbdFrame>::PushResult::kClosed) break;  // nobody takes frames
        if (pushed == BoundedQueue<RgbdFrame>::PushResult::kDroppedOldest) ++dropped_;
      } else if (!frames_->Push(std::move(*frame))) {
        break;  // the queue was closed: nobody takes frames any more
      }
    }
  } catch (const std::exception& e) {
    error_ = e.what();
  }
  NoteSourceStats();
  frames_->Close();
}

}  // namespace sightmap::mapping
