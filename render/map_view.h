// Where the mapper sends its map while it runs: the preview window or the off-screen progress
// writer (CreateMapView in map_view_factory.h picks one). Both draw on their own thread at their
// own rate; the mapper's calls never wait for a render.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>

#include <opencv2/core.hpp>

#include "render/map_scene.h"

namespace sightmap::render {

class MapView {
 public:
  virtual ~MapView() = default;

  // Hands over map changes; returns at once (the update is merged into what the drawing thread
  // has not taken yet, and a render that cannot keep up is skipped, never waited for).
  virtual void Submit(MapUpdate update) = 0;
  // The latest colour (BGR) and depth [mm] images; only the preview shows them. Copies them.
  virtual void SetLiveImages(const cv::Mat& bgr, const cv::Mat& depth_mm) {
    static_cast<void>(bgr);
    static_cast<void>(depth_mm);
  }
  // Polled by the mapper: the user paused capture (space in the preview).
  virtual bool paused() const { return false; }
  // Polled by the mapper: the user asked to stop (q or closing the window); save and return.
  virtual bool stop_requested() const { return false; }
  // Draws the final state (and writes the final image) and waits until it is done.
  virtual void Finish() = 0;
  // "preview window" or "progress images (FILE)", for logs.
  virtual std::string description() const = 0;
};

// The hand-over between the mapper and a drawing thread: Post merges into the pending update under
// a lock held for the merge only; the consumer swaps the pending update out. Keyframes are never
// dropped (they are the map), poses coalesce per keyframe, the camera and status keep the latest.
// So the pending update is bounded by the map itself, and render requests by one.
class MapMailbox {
 public:
  // Returns the post's sequence number (1, 2, ...).
  uint64_t Post(MapUpdate&& update) {
    uint64_t sequence;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pending_.Merge(std::move(update));
      sequence = ++posted_;
    }
    changed_.notify_all();
    return sequence;
  }
  // Waits until something was posted or `wake` is true (checked under the lock; notify with
  // Notify()) or the timeout passes; moves out the pending update and the sequence it covers.
  template <typename Predicate, typename Duration>
  MapUpdate Take(Predicate wake, Duration timeout, uint64_t* covers) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait_for(lock, timeout, [&] { return posted_ > taken_ || wake(); });
    MapUpdate update;
    std::swap(update, pending_);
    taken_ = posted_;
    *covers = taken_;
    return update;
  }
  // Wakes a waiting Take (after changing what its predicate reads).
  void Notify() {
    { std::lock_guard<std::mutex> lock(mutex_); }
    changed_.notify_all();
  }
  // The consumer finished with everything up to `sequence` (applied and, if due, rendered).
  void MarkDone(uint64_t sequence) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = std::max(done_, sequence);
    }
    done_changed_.notify_all();
  }
  // Blocks until everything posted before the call is done (tests, Finish).
  void WaitDone() {
    std::unique_lock<std::mutex> lock(mutex_);
    const uint64_t target = posted_;
    done_changed_.wait(lock, [&] { return done_ >= target; });
  }
  // Lets WaitDone callers go when the consumer has stopped for good.
  void MarkAllDone() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = UINT64_MAX;
    }
    done_changed_.notify_all();
  }
  template <typename Fn>
  void WithLock(Fn fn) {
    std::lock_guard<std::mutex> lock(mutex_);
    fn();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::condition_variable done_changed_;
  MapUpdate pending_;
  uint64_t posted_ = 0;
  uint64_t taken_ = 0;
  uint64_t done_ = 0;
};

}  // namespace sightmap::render
