#include "slam/place_index.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"

namespace sightmap::slam {

void KeepBestCandidates(int max_results, std::vector<PlaceCandidate>* candidates) {
  auto better = [](const PlaceCandidate& a, const PlaceCandidate& b) {
    return a.score > b.score || (a.score == b.score && a.id < b.id);
  };
  const size_t keep = std::min(candidates->size(), static_cast<size_t>(std::max(max_results, 0)));
  std::partial_sort(candidates->begin(), candidates->begin() + keep, candidates->end(), better);
  candidates->resize(keep);
}

void PlaceIndex::Add(int64_t id, BowVector bow) {
  if (Contains(id)) SIGHTMAP_THROW(InvalidArgument, "PlaceIndex already holds keyframe " << id);
  for (size_t i = 0; i < bow.size(); ++i) {
    if ((i > 0 && bow[i].first <= bow[i - 1].first) || !std::isfinite(bow[i].second) ||
        bow[i].second < 0.0f) {
      SIGHTMAP_THROW(InvalidArgument, "PlaceIndex::Add: the vector of keyframe "
                                          << id << " is not sorted by word id with finite "
                                          << "non-negative weights (entry " << i << ")");
    }
  }
  const uint32_t slot = static_cast<uint32_t>(ids_.size());
  for (const auto& [word, weight] : bow) {
    if (weight > 0.0f) postings_[word].push_back({slot, weight});
  }
  slot_of_id_.emplace(id, slot);
  ids_.push_back(id);
  bows_.push_back(std::move(bow));
}

std::vector<PlaceCandidate> PlaceIndex::Query(const BowVector& bow, int max_results,
                                              const std::function<bool(int64_t)>& accept) const {
  std::vector<PlaceCandidate> candidates;
  if (max_results <= 0 || ids_.empty()) return candidates;
  // Score = sum over shared words of min(query weight, keyframe weight) (Vocabulary::Score).
  // Summed in word order in double, as Score does, so both give the same number.
  std::vector<double> score(ids_.size(), 0.0);
  std::vector<uint32_t> touched;
  for (const auto& [word, weight] : bow) {
    if (!(weight > 0.0f)) continue;
    const auto postings = postings_.find(word);
    if (postings == postings_.end()) continue;
    for (const Posting& posting : postings->second) {
      if (score[posting.slot] == 0.0) touched.push_back(posting.slot);
      score[posting.slot] += std::min(weight, posting.weight);
    }
  }
  for (uint32_t slot : touched) {
    if (accept && !accept(ids_[slot])) continue;
    candidates.push_back({ids_[slot], std::min(score[slot], 1.0)});
  }
  KeepBestCandidates(max_results, &candidates);
  return candidates;
}

const BowVector& PlaceIndex::Get(int64_t id) const {
  const auto slot = slot_of_id_.find(id);
  if (slot == slot_of_id_.end()) {
    SIGHTMAP_THROW(InvalidArgument, "PlaceIndex holds no keyframe " << id);
  }
  return bows_[slot->second];
}

}  // namespace sightmap::slam
