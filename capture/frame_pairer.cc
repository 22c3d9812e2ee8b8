#include "capture/frame_pairer.h"

#include <cstdlib>

namespace sightmap::capture {

FramePairer::FramePairer(int64_t tolerance_ns) : tolerance_ns_(tolerance_ns) {}

void FramePairer::AddDepth(TimedImage depth) {
  pending_depth_.push_back(std::move(depth));
  while (pending_depth_.size() > kMaxPendingDepth) {
    TimedImage oldest = std::move(pending_depth_.front());
    pending_depth_.pop_front();
    Resolve(std::move(oldest), nullptr);
  }
}

void FramePairer::AddColor(TimedImage color) {
  // Only depth frames up to this colour frame's time are decided now, between it and the one
  // before; a later one waits, since the next colour frame may be nearer. (Deciding every pending
  // frame here left a depth stream running a frame ahead of colour unpaired for ever: OpenNI2's
  // dummy device does that now and then.)
  while (!pending_depth_.empty() && pending_depth_.front().timestamp_ns <= color.timestamp_ns) {
    TimedImage depth = std::move(pending_depth_.front());
    pending_depth_.pop_front();
    Resolve(std::move(depth), &color);
  }
  last_color_ = std::move(color);
}

void FramePairer::Finish() {
  while (!pending_depth_.empty()) {
    TimedImage depth = std::move(pending_depth_.front());
    pending_depth_.pop_front();
    Resolve(std::move(depth), nullptr);
  }
}

void FramePairer::Resolve(TimedImage depth, const TimedImage* next_color) {
  const TimedImage* best = nullptr;
  int64_t best_dt = 0;
  const TimedImage* previous_color = last_color_ ? &*last_color_ : nullptr;
  for (const TimedImage* candidate : {previous_color, next_color}) {
    if (!candidate) continue;
    const int64_t dt = std::llabs(candidate->timestamp_ns - depth.timestamp_ns);
    if (!best || dt < best_dt) {
      best = candidate;
      best_dt = dt;
    }
  }
  if (!best || best_dt > tolerance_ns_) {
    ++unpaired_;
    return;
  }
  // The colour image may serve two depth frames (a slower colour stream), so it is shared, not
  // moved; consumers treat frames as read-only.
  ready_.emplace_back(std::move(depth), *best);
}

std::optional<std::pair<TimedImage, TimedImage>> FramePairer::PopPair() {
  if (ready_.empty()) return std::nullopt;
  auto pair = std::move(ready_.front());
  ready_.pop_front();
  return pair;
}

}  // namespace sightmap::capture
