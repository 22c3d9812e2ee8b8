#include "slam/pose_graph_stages.h"

#include <numeric>

#include "core/check.h"

namespace sightmap::slam::internal {

Components::Components(size_t size) : parent_(size) {
  std::iota(parent_.begin(), parent_.end(), size_t{0});
}

size_t Components::Find(size_t i) {
  while (parent_[i] != i) {
    parent_[i] = parent_[parent_[i]];
    i = parent_[i];
  }
  return i;
}

void Components::Join(size_t a, size_t b) { parent_[Find(a)] = Find(b); }

std::vector<bool> SelectEdges(const EdgeEnds& ends, const std::vector<bool>& active,
                              const std::vector<bool>& free, std::optional<size_t> around) {
  SIGHTMAP_CHECK(active.size() == ends.size(), "one active flag an edge");
  SIGHTMAP_CHECK(!around || *around < free.size(), "pose index " << *around << " out of range");
  std::vector<bool> selected(active);
  if (around) {
    Components tied(free.size());
    for (size_t e = 0; e < ends.size(); ++e) {
      if (active[e]) tied.Join(ends[e].first, ends[e].second);
    }
    const size_t part = tied.Find(*around);
    for (size_t e = 0; e < ends.size(); ++e) {
      selected[e] = active[e] && tied.Find(ends[e].first) == part;
    }
  }
  // An edge with no free end has nothing to move.
  for (size_t e = 0; e < ends.size(); ++e) {
    selected[e] = selected[e] && (free[ends[e].first] || free[ends[e].second]);
  }
  return selected;
}

std::vector<bool> HeldPoses(const EdgeEnds& ends, const std::vector<bool>& solved,
                            const std::vector<bool>& ties, const std::vector<bool>& pinned) {
  SIGHTMAP_CHECK(solved.size() == ends.size() && ties.size() == ends.size(),
                 "one solved and one tie flag an edge");
  const size_t num_poses = pinned.size();
  std::vector<bool> in_problem(num_poses, false);
  Components components(num_poses);
  for (size_t e = 0; e < ends.size(); ++e) {
    if (!solved[e]) continue;
    const auto [a, b] = ends[e];
    in_problem[a] = in_problem[b] = true;
    if (ties[e]) components.Join(a, b);
  }
  std::vector<bool> component_held(num_poses, false);
  for (size_t i = 0; i < num_poses; ++i) {
    if (in_problem[i] && pinned[i]) component_held[components.Find(i)] = true;
  }
  std::vector<bool> held(num_poses, false);
  for (size_t i = 0; i < num_poses; ++i) {
    if (!in_problem[i]) continue;
    held[i] = pinned[i];
    if (!component_held[components.Find(i)]) {
      component_held[components.Find(i)] = true;
      held[i] = true;
    }
  }
  return held;
}

std::optional<size_t> WorstLoop(const std::vector<std::optional<double>>& loop_chi2,
                                double max_chi2) {
  std::optional<size_t> worst;
  double worst_chi2 = max_chi2;
  for (size_t e = 0; e < loop_chi2.size(); ++e) {
    if (loop_chi2[e] && *loop_chi2[e] > worst_chi2) {
      worst = e;
      worst_chi2 = *loop_chi2[e];
    }
  }
  return worst;
}

}  // namespace sightmap::slam::internal
