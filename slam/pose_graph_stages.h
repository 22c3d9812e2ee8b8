// The stages of PoseGraph's optimisation that decide what is solved, on poses by index (in id
// order) and edges as pairs of pose indices: which edges a scope puts in play, which poses a solve
// holds (the gauge), and which loop edge to switch off. Apart from the solver so that each has its
// own test (pose_graph_test.cc).
#pragma once

#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

namespace sightmap::slam::internal {

// Each edge's (from, to) pose indices.
using EdgeEnds = std::vector<std::pair<size_t, size_t>>;

// Disjoint sets over pose indices.
class Components {
 public:
  explicit Components(size_t size);
  size_t Find(size_t i);
  void Join(size_t a, size_t b);

 private:
  std::vector<size_t> parent_;
};

// The edges in play: the `active` ones, or with `around` those that active edges tie to pose
// `around`; of them, those with a `free` end (one flag a pose; with every flag set, all).
std::vector<bool> SelectEdges(const EdgeEnds& ends, const std::vector<bool>& active,
                              const std::vector<bool>& free, std::optional<size_t> around);

// The gauge of a solve: which poses it holds. `solved` marks the edges in the problem, `ties`
// those of them that tie their ends together (an edge without information does not), `pinned`
// the poses held whatever (fixed, or outside a window). Every pose a solved edge touches belongs
// to a component of tied poses; each component holds its pinned poses, or else its first pose
// (lowest index: the lowest id), so that no solve has a free gauge direction. Poses no solved
// edge touches are not held (they are not in the problem).
std::vector<bool> HeldPoses(const EdgeEnds& ends, const std::vector<bool>& solved,
                            const std::vector<bool>& ties, const std::vector<bool>& pinned);

// The loop edge to switch off after a solve: of the edges with a chi-square (nullopt: not a
// candidate), the one with the largest above `max_chi2` (the first of equals); nullopt when none
// is. Only the worst: a false loop also raises the chi-square of the correct loops near it.
std::optional<size_t> WorstLoop(const std::vector<std::optional<double>>& loop_chi2,
                                double max_chi2);

}  // namespace sightmap::slam::internal
