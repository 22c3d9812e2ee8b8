// A cell of a regular voxel grid packed into 64 bits, 21 bits per axis: +-1,048,576 cells from the
// origin (+-21 km at 2 cm). The PLY export sorts by it and the occlusion cloud hashes it.
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Core>

namespace sightmap {

// The key of the voxel of size `voxel_m` [m] holding `p` [m]; nullopt when `p` is not finite or
// lies beyond the packable range (nothing indoors does: a depth glitch on a wild pose).
std::optional<uint64_t> VoxelKeyOf(const Eigen::Vector3d& p, double voxel_m);
// The voxel's minimum corner [m].
Eigen::Vector3d VoxelCorner(uint64_t key, double voxel_m);

}  // namespace sightmap
