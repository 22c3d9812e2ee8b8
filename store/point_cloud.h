// The model's point cloud as a PLY file: every keyframe's depth back-projected with its
// intrinsics and optimised world_from_cam, voxel downsampled, optionally cleaned of outliers.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "store/model.h"

namespace sightmap::store {

struct PlyExportOptions {
  // Back-project every pixel_step-th pixel along u and v (16x fewer points at 4) [px].
  int pixel_step = 4;
  // Depth outside [min_depth_m, max_depth_m] is dropped: Kinect-class depth is noisy far away [m].
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  // Voxel grid leaf size [m]; 0 keeps every back-projected point.
  double voxel_size_m = 0.02;
  // Statistical outlier removal: drop points whose mean distance to their `outlier_neighbours`
  // nearest neighbours is more than `outlier_stddev` standard deviations above the average.
  bool remove_outliers = false;
  int outlier_neighbours = 20;
  double outlier_stddev = 2.0;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const PlyExportOptions& options);
void from_json(const nlohmann::json& json, PlyExportOptions& options);

struct PlyExportStats {
  int64_t keyframes = 0;
  int64_t back_projected_points = 0;
  int64_t written_points = 0;
};

struct ColoredPoint {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  // world [m]
  uint8_t red = 0;
  uint8_t green = 0;
  uint8_t blue = 0;
};

// Writes binary little-endian PLY with x y z (float) red green blue (uchar) per vertex; throws
// Error when the model has no keyframes or the file cannot be written.
PlyExportStats ExportPly(const Model& model, const std::string& path,
                         const PlyExportOptions& options = {});

// Reads a PLY point cloud (ascii or binary little-endian; x y z of any scalar type, and red green
// blue as uchar or none) back, for tests and tools. Throws Error saying what is wrong with a file
// it cannot read.
std::vector<ColoredPoint> ReadPly(const std::string& path);

}  // namespace sightmap::store
