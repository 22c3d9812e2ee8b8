#include "core/voxel_key.h"

#include <cmath>

namespace sightmap {
namespace {

constexpr int kBits = 21;
constexpr int64_t kAxisOffset = int64_t{1} << (kBits - 1);
constexpr uint64_t kAxisMask = (uint64_t{1} << kBits) - 1;

}  // namespace

std::optional<uint64_t> VoxelKeyOf(const Eigen::Vector3d& p, double voxel_m) {
  uint64_t key = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double cell = std::floor(p[axis] / voxel_m);
    // Also false for NaN.
    if (!(cell >= -static_cast<double>(kAxisOffset) && cell < static_cast<double>(kAxisOffset))) {
      return std::nullopt;
    }
    key |= static_cast<uint64_t>(static_cast<int64_t>(cell) + kAxisOffset) << (kBits * axis);
  }
  return key;
}

Eigen::Vector3d VoxelCorner(uint64_t key, double voxel_m) {
  Eigen::Vector3d corner;
  for (int axis = 0; axis < 3; ++axis) {
    const int64_t cell = static_cast<int64_t>((key >> (kBits * axis)) & kAxisMask) - kAxisOffset;
    corner[axis] = static_cast<double>(cell) * voxel_m;
  }
  return corner;
}

}  // namespace sightmap
