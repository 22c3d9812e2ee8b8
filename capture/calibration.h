// An RGB-D calibration file (JSON) that overrides what a source would otherwise derive:
//
//   {
//     "color": {"width": 640, "height": 480, "fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5},
//     "depth": {"width": 640, "height": 480, "fx": 575.8, "fy": 575.8, "cx": 319.5, "cy": 239.5},
//     "color_from_depth": {"rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1],   // row-major 3x3
//                          "translation_m": [-0.025, 0, 0]}
//   }
//
// Every block is optional. Intrinsics given for another resolution are scaled to the stream's.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "core/camera.h"

namespace sightmap::capture {

struct RgbdCalibration {
  std::optional<Intrinsics> color;
  std::optional<Intrinsics> depth;
  // Maps points from the depth camera's frame to the colour camera's frame [m].
  std::optional<Eigen::Isometry3d> color_from_depth;
};

// Throws sightmap::Error naming the file and the offending field when it cannot be used.
RgbdCalibration ReadCalibrationFile(const std::string& path);

// Writes the same format (used by tests and by `probe` to save what a source derived).
void WriteCalibrationFile(const std::string& path, const RgbdCalibration& calibration);

}  // namespace sightmap::capture
