// Place recognition over keyframes: an inverted index from visual words to the keyframes that
// contain them, scored with Vocabulary::Score.
#pragma once

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "slam/vocabulary.h"

namespace sightmap::slam {

struct PlaceCandidate {
  int64_t id = -1;  // the keyframe's id as given to the index's Add
  // Vocabulary::Score of the query and the keyframe (PlaceIndex), or the share of the query's
  // descriptors that voted for it (VoteIndex); in (0, 1].
  double score = 0.0;
};

// Sorts `candidates` best first (higher score, ties by smaller id) and keeps the first
// max_results.
void KeepBestCandidates(int max_results, std::vector<PlaceCandidate>* candidates);

// Keyframes' BowVectors under an inverted index (word -> keyframes with their weights). A query
// walks only the postings of its own words, so it costs O(query words x postings per word) plus
// clearing one number per keyframe, not a Score with every keyframe. Not thread-safe for Add;
// concurrent Query calls on an index nobody adds to are safe.
class PlaceIndex {
 public:
  // Throws InvalidArgument on a duplicate id or a vector that is not sorted by word id with
  // finite non-negative weights.
  void Add(int64_t id, BowVector bow);

  bool Contains(int64_t id) const { return slot_of_id_.count(id) != 0; }
  size_t size() const { return ids_.size(); }

  // The `max_results` keyframes sharing words with `bow` that score highest, highest first (ties
  // by smaller id). Keyframes for which `accept` (when given) returns false are left out, e.g.
  // the recent keyframes of the query's own segment. Keyframes sharing no word (score 0) are
  // never returned.
  std::vector<PlaceCandidate> Query(const BowVector& bow, int max_results,
                                    const std::function<bool(int64_t)>& accept = nullptr) const;

  // The vector added for `id`; throws InvalidArgument for an unknown id.
  const BowVector& Get(int64_t id) const;

 private:
  struct Posting {
    uint32_t slot;  // index into ids_ / bows_
    float weight;
  };
  std::vector<int64_t> ids_;
  std::vector<BowVector> bows_;
  std::unordered_map<int64_t, uint32_t> slot_of_id_;
  std::unordered_map<int, std::vector<Posting>> postings_;
};

}  // namespace sightmap::slam
