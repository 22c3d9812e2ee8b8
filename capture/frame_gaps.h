// Counts the frames a stream numbered that were never read. OpenNI2 keeps only a stream's newest
// frame, so a reader that falls behind a live sensor (or a recording played at its recorded pace)
// loses frames without an error: the gaps in the frame numbers are their only trace.
#pragma once

#include <cstdint>
#include <optional>

namespace sightmap::capture {

class FrameGaps {
 public:
  // A recording numbers its frames from 1, so frames lost before the first read one count too; a
  // live device numbers from wherever it is (`first_number` nullopt).
  explicit FrameGaps(std::optional<int64_t> first_number) {
    if (first_number) last_ = *first_number - 1;
  }

  // Records a read frame; returns how many frames were missed just before it. A number that goes
  // back (a restarted device) starts the count again.
  int64_t Add(int64_t number) {
    const int64_t missed = last_ && number > *last_ + 1 ? number - *last_ - 1 : 0;
    last_ = number;
    missed_ += missed;
    return missed;
  }

  int64_t missed() const { return missed_; }

 private:
  std::optional<int64_t> last_;
  int64_t missed_ = 0;
};

}  // namespace sightmap::capture
