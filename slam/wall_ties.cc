#include "slam/wall_ties.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"

namespace sightmap::slam {
namespace {

// The spread of `values` between their 2nd and 98th percentiles (a stray patch does not count).
double Spread(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const auto at = [&values](double q) {
    return values[static_cast<size_t>(q * static_cast<double>(values.size() - 1))];
  };
  return at(0.98) - at(0.02);
}

// The centres of the offsets' densest windows (`min_support` patches within the bins of
// `peak_halfwidth_m` around a bin), strongest first, and the windows' half width [m].
std::pair<std::vector<double>, double> OffsetPeaks(const std::vector<double>& offsets,
                                                   const WallTieOptions& options) {
  const auto [lowest, highest] = std::minmax_element(offsets.begin(), offsets.end());
  const double origin = *lowest;
  const int bins = static_cast<int>((*highest - origin) / options.bin_m) + 1;
  std::vector<int> counts(static_cast<size_t>(bins), 0);
  for (double offset : offsets) ++counts[static_cast<size_t>((offset - origin) / options.bin_m)];
  const int half =
      std::max(1, static_cast<int>(std::lround(options.peak_halfwidth_m / options.bin_m)));
  std::vector<std::pair<int, int>> windows;  // (patches within half bins, bin)
  for (int b = 0; b < bins; ++b) {
    int sum = 0;
    for (int k = std::max(0, b - half); k <= std::min(bins - 1, b + half); ++k) sum += counts[k];
    if (sum >= options.min_support) windows.emplace_back(sum, b);
  }
  std::sort(windows.rbegin(), windows.rend());
  std::vector<double> centres;
  for (const auto& [sum, bin] : windows) centres.push_back(origin + (bin + 0.5) * options.bin_m);
  return {centres, (half + 0.5) * options.bin_m};
}

// The planes along one signed axis (`axis` of cam_from_axes, `sign`): the offsets' peaks at
// least min_separation_m from a stronger one, wide and tall enough to be a wall or a floor.
void FindPlanesAlong(const std::vector<PlanePatch>& patches, const Eigen::Matrix3d& cam_from_axes,
                     int axis, double sign, const WallTieOptions& options,
                     std::vector<AxisPlane>* planes) {
  const Eigen::Vector3d normal = sign * cam_from_axes.col(axis);
  const Eigen::Vector3d across = cam_from_axes.col((axis + 1) % 3);
  const Eigen::Vector3d along = cam_from_axes.col((axis + 2) % 3);
  const double min_cos = std::cos(DegToRad(options.assign_deg));
  std::vector<const PlanePatch*> on_axis;
  std::vector<double> offsets;
  for (const PlanePatch& patch : patches) {
    if (patch.normal.dot(normal) < min_cos) continue;
    on_axis.push_back(&patch);
    offsets.push_back(normal.dot(patch.point));
  }
  if (static_cast<int>(offsets.size()) < options.min_support) return;
  const auto [centres, reach] = OffsetPeaks(offsets, options);
  std::vector<double> taken;
  for (double centre : centres) {
    const bool near_stronger = std::any_of(taken.begin(), taken.end(), [&](double offset) {
      return std::abs(offset - centre) < options.min_separation_m;
    });
    if (near_stronger) continue;
    taken.push_back(centre);
    AxisPlane plane;
    plane.normal_cam = normal;
    double offset_sum = 0.0;
    std::vector<double> across_m, along_m;
    for (size_t i = 0; i < offsets.size(); ++i) {
      if (std::abs(offsets[i] - centre) > reach) continue;
      offset_sum += offsets[i];
      plane.centroid_cam += on_axis[i]->point;
      across_m.push_back(across.dot(on_axis[i]->point));
      along_m.push_back(along.dot(on_axis[i]->point));
      ++plane.support;
    }
    if (plane.support < options.min_support || Spread(across_m) < options.min_extent_m ||
        Spread(along_m) < options.min_extent_m) {
      continue;
    }
    plane.offset_m = offset_sum / plane.support;
    plane.centroid_cam /= plane.support;
    planes->push_back(plane);
  }
}

// A plane as the map places it: on which signed axis of the world, at which offset along it.
struct Sighting {
  size_t keyframe = 0;
  size_t plane = 0;
  int side = 0;  // axis * 2 + (positive ? 1 : 0)
  double world_offset_m = 0.0;
  Eigen::Vector3d centroid_world;
  std::vector<double> others_m;  // the world offsets of the keyframe's other planes on this side
};

std::vector<Sighting> PlaceSightings(const std::vector<PlaneSightings>& keyframes,
                                     const Eigen::Matrix3d& world_from_axes,
                                     const WallTieOptions& options) {
  const double min_cos = std::cos(DegToRad(options.snap_deg));
  std::vector<Sighting> sightings;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    const Eigen::Isometry3d& world_from_cam = keyframes[k].world_from_cam;
    for (size_t p = 0; p < keyframes[k].planes.size(); ++p) {
      const AxisPlane& plane = keyframes[k].planes[p];
      const Eigen::Vector3d normal_world = world_from_cam.linear() * plane.normal_cam;
      for (int axis = 0; axis < 3; ++axis) {
        const double cosine = normal_world.dot(world_from_axes.col(axis));
        if (std::abs(cosine) < min_cos) continue;
        const Eigen::Vector3d along =
            cosine > 0.0 ? world_from_axes.col(axis).eval() : (-world_from_axes.col(axis)).eval();
        Sighting sighting;
        sighting.keyframe = k;
        sighting.plane = p;
        sighting.side = axis * 2 + (cosine > 0.0 ? 1 : 0);
        sighting.world_offset_m = plane.offset_m + along.dot(world_from_cam.translation());
        sighting.centroid_world = world_from_cam * plane.centroid_cam;
        sightings.push_back(sighting);
      }
    }
  }
  // A keyframe's sightings are consecutive.
  for (size_t i = 0; i < sightings.size(); ++i) {
    for (size_t j = i + 1; j < sightings.size() && sightings[j].keyframe == sightings[i].keyframe;
         ++j) {
      if (sightings[j].side != sightings[i].side) continue;
      sightings[i].others_m.push_back(sightings[j].world_offset_m);
      sightings[j].others_m.push_back(sightings[i].world_offset_m);
    }
  }
  return sightings;
}

// A candidate tie: (the smaller support of its two planes, its two sightings' indices in a side).
using CandidatePair = std::tuple<int, size_t, size_t>;
// (part, part, side, wall): the pairs one part pair could be tied by on one wall.
using WallKey = std::tuple<int, int, int, long>;

// Whether the keyframe of `sighting` holds no other plane on its side within `gap` of `offset`.
bool OnlyPlaneNear(const Sighting& sighting, double offset, double gap) {
  return std::none_of(sighting.others_m.begin(), sighting.others_m.end(),
                      [&](double other) { return std::abs(other - offset) < gap; });
}

// Of one part pair's candidate ties on one wall (support, i, j into `side`), those whose offset
// gaps agree with the most others (within `agree_m`): a keyframe that took a cupboard's front for
// the wall behind it is outvoted by the pairs that saw the wall. Empty without a majority of at
// least `min_agreeing`.
std::vector<CandidatePair> AgreeingPairs(const std::vector<CandidatePair>& pairs,
                                         const std::vector<Sighting>& side,
                                         const std::vector<PlaneSightings>& keyframes,
                                         const WallTieOptions& options) {
  std::vector<double> gaps;
  for (const auto& [support, i, j] : pairs) {
    // Oriented from the lower part to the higher, whichever sighting came first.
    const double gap = side[j].world_offset_m - side[i].world_offset_m;
    gaps.push_back(keyframes[side[i].keyframe].part < keyframes[side[j].keyframe].part ? gap
                                                                                       : -gap);
  }
  size_t best = 0;
  int best_count = 0;
  for (size_t c = 0; c < gaps.size(); ++c) {
    const int count = static_cast<int>(std::count_if(gaps.begin(), gaps.end(), [&](double gap) {
      return std::abs(gap - gaps[c]) <= options.agree_m;
    }));
    if (count > best_count) {
      best_count = count;
      best = c;
    }
  }
  std::vector<CandidatePair> agreeing;
  if (best_count < options.min_agreeing || 2 * best_count <= static_cast<int>(gaps.size())) {
    return agreeing;
  }
  for (size_t c = 0; c < gaps.size(); ++c) {
    if (std::abs(gaps[c] - gaps[best]) <= options.agree_m) agreeing.push_back(pairs[c]);
  }
  return agreeing;
}

// Pairs of sightings of one wall by two parts, per (part, part, side, wall): on one side,
// within max_offset_gap_m and max_centroid_distance_m, neither keyframe holding another plane of
// that side near the other's. Sorts each side of `by_side` by offset (the pairs index into it).
std::map<WallKey, std::vector<CandidatePair>> CandidatePairs(
    const std::vector<PlaneSightings>& keyframes, const WallTieOptions& options,
    std::map<int, std::vector<Sighting>>* by_side) {
  std::map<WallKey, std::vector<CandidatePair>> candidates;
  for (auto& [side_index, side] : *by_side) {
    std::sort(side.begin(), side.end(), [](const Sighting& a, const Sighting& b) {
      return a.world_offset_m < b.world_offset_m;
    });
    for (size_t i = 0; i < side.size(); ++i) {
      for (size_t j = i + 1; j < side.size(); ++j) {
        const double gap = side[j].world_offset_m - side[i].world_offset_m;
        if (gap > options.max_offset_gap_m) break;
        const PlaneSightings& a = keyframes[side[i].keyframe];
        const PlaneSightings& b = keyframes[side[j].keyframe];
        if (a.part == b.part) continue;
        if ((side[i].centroid_world - side[j].centroid_world).norm() >
            options.max_centroid_distance_m) {
          continue;
        }
        if (!OnlyPlaneNear(side[i], side[j].world_offset_m, options.min_unique_gap_m) ||
            !OnlyPlaneNear(side[j], side[i].world_offset_m, options.min_unique_gap_m)) {
          continue;
        }
        const int support =
            std::min(a.planes[side[i].plane].support, b.planes[side[j].plane].support);
        const long wall = std::lround(0.5 * (side[i].world_offset_m + side[j].world_offset_m) /
                                      options.min_unique_gap_m);
        candidates[{std::min(a.part, b.part), std::max(a.part, b.part), side_index, wall}]
            .emplace_back(support, i, j);
      }
    }
  }
  return candidates;
}

}  // namespace

bool WallTieOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!(assign_deg > 0.0 && assign_deg < 45.0)) return fail("assign_deg must be in (0, 45)");
  if (!(bin_m > 0.0)) return fail("bin_m must be positive");
  if (!(peak_halfwidth_m >= bin_m)) return fail("peak_halfwidth_m must be at least bin_m");
  if (min_support < 3) return fail("min_support must be at least 3");
  if (!(min_separation_m > 0.0)) return fail("min_separation_m must be positive");
  if (!(min_extent_m >= 0.0)) return fail("min_extent_m must not be negative");
  if (!(max_offset_gap_m > 0.0)) return fail("max_offset_gap_m must be positive");
  if (!(max_centroid_distance_m > 0.0)) return fail("max_centroid_distance_m must be positive");
  if (!(min_unique_gap_m >= max_offset_gap_m)) {
    return fail("min_unique_gap_m must be at least max_offset_gap_m");
  }
  if (!(snap_deg > 0.0 && snap_deg < 45.0)) return fail("snap_deg must be in (0, 45)");
  if (max_ties_per_wall < 1) return fail("max_ties_per_wall must be at least 1");
  if (!(agree_m > 0.0)) return fail("agree_m must be positive");
  if (min_agreeing < 1) return fail("min_agreeing must be at least 1");
  if (!(sigma_m > 0.0)) return fail("sigma_m must be positive");
  return true;
}

std::vector<AxisPlane> FindAxisPlanes(const std::vector<PlanePatch>& patches,
                                      const Eigen::Matrix3d& cam_from_axes,
                                      const WallTieOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::vector<AxisPlane> planes;
  for (int axis = 0; axis < 3; ++axis) {
    for (double sign : {1.0, -1.0}) {
      FindPlanesAlong(patches, cam_from_axes, axis, sign, options, &planes);
    }
  }
  return planes;
}

std::vector<PlaneTie> TieWalls(const std::vector<PlaneSightings>& keyframes,
                               const Eigen::Matrix3d& world_from_axes,
                               const WallTieOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::map<int, std::vector<Sighting>> by_side;
  for (Sighting& sighting : PlaceSightings(keyframes, world_from_axes, options)) {
    by_side[sighting.side].push_back(std::move(sighting));
  }
  std::vector<PlaneTie> ties;
  for (const auto& [key, candidates] : CandidatePairs(keyframes, options, &by_side)) {
    const std::vector<Sighting>& side = by_side.at(std::get<2>(key));
    std::vector<CandidatePair> pairs = AgreeingPairs(candidates, side, keyframes, options);
    std::sort(pairs.rbegin(), pairs.rend());
    if (static_cast<int>(pairs.size()) > options.max_ties_per_wall) {
      pairs.resize(static_cast<size_t>(options.max_ties_per_wall));
    }
    for (const auto& [support, i, j] : pairs) {
      const PlaneSightings& a = keyframes[side[i].keyframe];
      const PlaneSightings& b = keyframes[side[j].keyframe];
      const AxisPlane& plane_a = a.planes[side[i].plane];
      const AxisPlane& plane_b = b.planes[side[j].plane];
      PlaneTie tie;
      tie.from = a.id;
      tie.to = b.id;
      tie.normal_in_from = plane_a.normal_cam;
      // Both on one plane: offset_a + n . p_a = offset_b + n . p_b in the world.
      tie.offset_m = plane_a.offset_m - plane_b.offset_m;
      tie.sigma_m = options.sigma_m;
      ties.push_back(tie);
    }
  }
  return ties;
}

SIGHTMAP_OPTIONS_JSON(WallTieOptions, assign_deg, bin_m, peak_halfwidth_m, min_support,
                      min_separation_m, min_extent_m, max_offset_gap_m, max_centroid_distance_m,
                      min_unique_gap_m, snap_deg, agree_m, min_agreeing, max_ties_per_wall, sigma_m)

}  // namespace sightmap::slam
