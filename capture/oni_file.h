// Reads what OpenNI2's file driver does not tell: the ONI header and the properties an OpenNI 1
// recorder wrote per node (OpenNI2 drops "AlternativeViewPoint", the OpenNI 1 name for depth
// registered to the colour camera, so without this a registered recording would be registered
// twice and every 3D point shifted by several pixels).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace sightmap::capture {

struct OniFileInfo {
  int version_major = 0;
  int version_minor = 0;
  int version_maintenance = 0;
  uint64_t max_timestamp_us = 0;  // 0: the recording holds no frames; ~0: not written
  // What the recorder said about depth registration; nullopt when the file does not say.
  std::optional<bool> depth_registered_to_color;
};

// Validates the header and scans the records before the first frame. Throws sightmap::Error with a
// one-line reason for a missing, empty, non-ONI, ONI 1.0.0, frameless or cut-off file.
OniFileInfo ReadOniFileInfo(const std::string& path);

}  // namespace sightmap::capture
