#include "capture/keyframe_sampler.h"

#include <cmath>

#include "core/check.h"
#include "core/options_json.h"

namespace sightmap::capture {

bool KeyframeSamplerOptions::Check(std::string* error) const {
  if (!(rate_hz >= 0.0) || !std::isfinite(rate_hz) || rate_hz > 1000.0) {
    if (error) *error = "rate_hz must be in [0, 1000] (0 keeps every frame)";
    return false;
  }
  return true;
}

KeyframeSampler::KeyframeSampler(const KeyframeSamplerOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  period_ns_ =
      options.rate_hz > 0.0 ? static_cast<int64_t>(std::llround(1e9 / options.rate_hz)) : 0;
}

TimestampNs KeyframeSampler::NextGridPoint(TimestampNs timestamp_ns) const {
  // Floor division, for clocks that start below zero.
  const int64_t periods = timestamp_ns / period_ns_ - (timestamp_ns % period_ns_ < 0 ? 1 : 0);
  return (periods + 1) * period_ns_;
}

bool KeyframeSampler::Accept(TimestampNs timestamp_ns) {
  if (period_ns_ == 0) return true;
  const bool first = !next_due_ns_;
  const bool went_back = next_due_ns_ && timestamp_ns < *next_due_ns_ - period_ns_;
  if (!first && !went_back && timestamp_ns < *next_due_ns_) return false;
  // The next grid point after this frame: past any a gap in the stream jumped over.
  next_due_ns_ = NextGridPoint(timestamp_ns);
  return true;
}

SIGHTMAP_OPTIONS_JSON(KeyframeSamplerOptions, rate_hz)

}  // namespace sightmap::capture
