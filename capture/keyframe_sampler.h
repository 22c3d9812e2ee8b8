// Picks keyframes from a faster stream at a fixed rate by timestamp (the paper keeps one frame per
// second). Works on timestamps only, so every source samples the same way.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "core/rgbd_frame.h"

namespace sightmap::capture {

struct KeyframeSamplerOptions {
  // Keyframes per second [Hz]; 0 keeps every frame.
  double rate_hz = 1.0;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const KeyframeSamplerOptions& options);
void from_json(const nlohmann::json& json, KeyframeSamplerOptions& options);

class KeyframeSampler {
 public:
  explicit KeyframeSampler(const KeyframeSamplerOptions& options = KeyframeSamplerOptions());

  // True when the frame at `timestamp_ns` should become a keyframe. The first frame always does;
  // then the first frame at or after each whole period of the source's clock (a grid that does
  // not depend on where the stream starts: a replay resumed after any stored frame keeps the
  // keyframes the uninterrupted replay kept), so jitter does not add up to drift. A timestamp that
  // goes backwards (a restarted device) starts again as a first frame.
  bool Accept(TimestampNs timestamp_ns);

 private:
  // The first multiple of the period after `timestamp_ns`.
  TimestampNs NextGridPoint(TimestampNs timestamp_ns) const;

  int64_t period_ns_;
  std::optional<TimestampNs> next_due_ns_;
};

}  // namespace sightmap::capture
