// Pairs depth frames with colour frames by timestamp. Devices and recordings deliver the two
// streams interleaved and not always one-to-one (openni2-24f.oni: 24 depth, 23 colour), so each
// depth frame takes the nearest colour frame in time, which may arrive just after it.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <utility>

#include <opencv2/core.hpp>

#include "core/rgbd_frame.h"

namespace sightmap::capture {

struct TimedImage {
  TimestampNs timestamp_ns = 0;
  cv::Mat image;
};

class FramePairer {
 public:
  // Pairs further apart than `tolerance_ns` are not made; their depth frame is counted unpaired.
  explicit FramePairer(int64_t tolerance_ns);

  void AddDepth(TimedImage depth);
  void AddColor(TimedImage color);
  // End of stream: pending depth frames take the last colour frame if it is close enough.
  void Finish();

  // The oldest ready (depth, colour) pair, in depth-time order.
  std::optional<std::pair<TimedImage, TimedImage>> PopPair();

  int64_t unpaired_depth_frames() const { return unpaired_; }

 private:
  // Depth frames waiting for the next colour frame; bounded so a dead colour stream cannot grow it.
  static constexpr size_t kMaxPendingDepth = 8;

  void Resolve(TimedImage depth, const TimedImage* next_color);

  int64_t tolerance_ns_;
  std::deque<TimedImage> pending_depth_;
  std::optional<TimedImage> last_color_;
  std::deque<std::pair<TimedImage, TimedImage>> ready_;
  int64_t unpaired_ = 0;
};

}  // namespace sightmap::capture
