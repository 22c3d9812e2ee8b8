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
  // then one per period on a grid anchored at the first frame, so jitter does not add up to drift.
  // A timestamp that goes backwards (a restarted device) re-anchors the grid.
  bool Accept(TimestampNs timestamp_ns);

 private:
  int64_t period_ns_;
  std::optional<TimestampNs> next_due_ns_;
};

}  // namespace sightmap::capture
