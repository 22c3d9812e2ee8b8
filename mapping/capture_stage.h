// The capture stage of `sightmap map`: a source's frames, read on this stage's own thread and put
// on the frame queue for the tracking stage.
//
// A live sensor (or a recording played at its recorded pace) never waits: when the queue is full
// its oldest frame is dropped and counted, so the tracker always gets the newest frames once it is
// free. A recording, a folder or the simulator waits for room, so a replay drops nothing.
//
// Which frames go on: every `take_every`th from `start_frame` when the frames are tracked, or one
// per keyframe period (`sampler`) when they are not, so that a live sensor then drops keyframes the
// mapper cannot take rather than the frames in between.
//
// With a map view: about ten live images a second go to it, and while the view is paused a live
// sensor's frames pass by unused and a replay waits for the user.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "capture/keyframe_sampler.h"
#include "capture/rgbd_source.h"
#include "core/rgbd_frame.h"
#include "mapping/bounded_queue.h"
#include "mapping/map_view_feed.h"

namespace sightmap::mapping {

struct CaptureStageOptions {
  // Frames with a lower index are read and skipped (continue a recording from frame N).
  int64_t start_frame = 0;
  // Frames stamped at or before this are read and skipped too: a resumed replay continues after
  // the last frame the model stored from it [ns, the source's clock].
  std::optional<TimestampNs> after_timestamp_ns;
  // Never wait for room in the frame queue: drop the frame and count it.
  bool live = false;
  // Pass on one frame per keyframe period (sampler) instead of every take_every-th frame.
  bool sample_keyframes = false;
  capture::KeyframeSamplerOptions sampler;
  int take_every = 1;  // [frames]
  // A replay (not live) reads, decodes or renders as fast as the stages after it take its frames,
  // so on a busy machine it competes with tracking and mapping for the cores. Its thread (and the
  // threads it starts) runs this much lower (Linux nice, per thread, 0-19): the replay then waits
  // for the stages whose latency the user sees instead of slowing them. A live source keeps its
  // priority: it must not miss the sensor's frames. Measured: MappingOptions::
  // replay_nice_increment.
  int replay_nice_increment = 10;

  bool Check(std::string* error) const;
};

class CaptureStage {
 public:
  // Starts the thread. `source`, `frames` and `view` (may be null) must outlive the stage; the
  // frame queue is closed when the stage ends (the source ended or failed, or Stop()).
  CaptureStage(capture::RgbdSource* source, const CaptureStageOptions& options,
               BoundedQueue<RgbdFrame>* frames, MapViewFeed* view = nullptr);
  ~CaptureStage();  // Stop() and Join()
  CaptureStage(const CaptureStage&) = delete;
  CaptureStage& operator=(const CaptureStage&) = delete;

  // The thread ends after the frame in hand (a blocking sensor read returns first); frames still
  // queued are discarded.
  void Stop();
  void Join();

  // Any thread.
  int64_t frames_read() const { return frames_read_.load(); }
  // Frames read, or missed by the source behind a live pace: how far through the source it is.
  int64_t frames_passed() const { return frames_read_.load() + source_missed_.load(); }
  // Frames read and skipped as before the start (start_frame, after_timestamp_ns).
  int64_t frames_skipped() const { return frames_skipped_.load(); }
  // Frames lost because the pipeline fell behind a live source: replaced in the driver before
  // they were read (the source's missed depth frames), or dropped from the full frame queue.
  int64_t dropped_frames() const { return dropped_.load() + source_missed_.load(); }
  // Depth frames the source dropped for lack of a colour frame in time.
  int64_t unpaired_frames() const { return unpaired_.load(); }
  // Why the source failed (its one-line error), or nothing; valid after Join().
  const std::optional<std::string>& error() const { return error_; }

 private:
  void Run();
  bool BeforeStart(int64_t index, TimestampNs timestamp_ns) const;
  // Passes over the frames before the start without producing them, as far as the source can
  // tell their stamps (PeekStamp); the rest are read and skipped in Run().
  void SkipCheaply();
  bool Wanted(const RgbdFrame& frame);
  // Waits while a view pauses a replay; false when a live frame should pass by unused.
  bool WaitWhilePaused();
  // Copies the source's own losses for other threads to read.
  void NoteSourceStats();

  capture::RgbdSource* source_;
  CaptureStageOptions options_;
  BoundedQueue<RgbdFrame>* frames_;
  MapViewFeed* view_;
  capture::KeyframeSampler sampler_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> frames_read_{0};
  std::atomic<int64_t> frames_skipped_{0};
  std::atomic<int64_t> dropped_{0};
  std::atomic<int64_t> source_missed_{0};
  std::atomic<int64_t> unpaired_{0};
  std::optional<std::string> error_;  // written by the thread before it ends
  std::thread thread_;
};

}  // namespace sightmap::mapping
