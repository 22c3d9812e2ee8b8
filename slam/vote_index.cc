#include "slam/vote_index.h"

#include <algorithm>
#include <cstring>

#include "core/check.h"
#include "slam/hamming.h"

namespace sightmap::slam {
namespace {

void CheckRows(const cv::Mat& descriptors, const std::vector<int>& words, const char* what) {
  if (descriptors.empty() && words.empty()) return;
  if (descriptors.type() != CV_8U || descriptors.cols != 32) {
    SIGHTMAP_THROW(InvalidArgument, "VoteIndex: " << what << " descriptors are not ORB's (CV_8U, "
                                                  << "32 columns)");
  }
  if (static_cast<size_t>(descriptors.rows) != words.size()) {
    SIGHTMAP_THROW(InvalidArgument, "VoteIndex: " << what << " has " << descriptors.rows
                                                  << " descriptors but " << words.size()
                                                  << " words");
  }
}

}  // namespace

VoteIndex::VoteIndex(int max_hamming) : max_hamming_(max_hamming) {
  if (max_hamming < 0 || max_hamming > 256) {
    SIGHTMAP_THROW(InvalidArgument, "VoteIndex: max_hamming must be in [0, 256]");
  }
}

void VoteIndex::Add(int64_t id, const cv::Mat& descriptors, const std::vector<int>& words) {
  if (Contains(id)) SIGHTMAP_THROW(InvalidArgument, "VoteIndex already holds keyframe " << id);
  CheckRows(descriptors, words, "a keyframe's");
  std::vector<Entry> entries(static_cast<size_t>(descriptors.rows));
  for (int r = 0; r < descriptors.rows; ++r) {
    Entry& entry = entries[static_cast<size_t>(r)];
    entry.word = words[static_cast<size_t>(r)];
    std::memcpy(entry.bits.data(), descriptors.ptr<uint8_t>(r), 32);
  }
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& a, const Entry& b) { return a.word < b.word; });
  keyframes_.emplace(id, std::move(entries));
}

// The popcnt clone serves CPUs with the instruction (a photo's votes compare every keyframe).
__attribute__((target_clones("popcnt", "default"))) int VoteIndex::Votes(
    const std::vector<Entry>& query, const std::vector<Entry>& keyframe) const {
  int votes = 0;
  size_t q = 0;
  size_t k = 0;
  while (q < query.size() && k < keyframe.size()) {
    if (query[q].word < keyframe[k].word) {
      ++q;
    } else if (keyframe[k].word < query[q].word) {
      ++k;
    } else {
      const int word = query[q].word;
      size_t k_end = k;
      while (k_end < keyframe.size() && keyframe[k_end].word == word) ++k_end;
      // Each query row of the word votes once, however many of the keyframe's descriptors (a
      // repeated texture) lie within reach.
      for (; q < query.size() && query[q].word == word; ++q) {
        for (size_t j = k; j < k_end; ++j) {
          if (Hamming256(query[q].bits.data(), keyframe[j].bits.data()) <= max_hamming_) {
            ++votes;
            break;
          }
        }
      }
      k = k_end;
    }
  }
  return votes;
}

std::vector<PlaceCandidate> VoteIndex::Rank(const cv::Mat& descriptors,
                                            const std::vector<int>& words,
                                            const std::vector<int64_t>& shortlist,
                                            int max_results) const {
  CheckRows(descriptors, words, "the query");
  std::vector<const std::vector<Entry>*> listed;
  for (int64_t id : shortlist) {
    const auto found = keyframes_.find(id);
    if (found == keyframes_.end())
      SIGHTMAP_THROW(InvalidArgument, "VoteIndex holds no keyframe " << id);
    listed.push_back(&found->second);
  }
  std::vector<PlaceCandidate> candidates;
  if (max_results <= 0 || descriptors.rows == 0) return candidates;
  std::vector<Entry> query(static_cast<size_t>(descriptors.rows));
  for (int r = 0; r < descriptors.rows; ++r) {
    query[static_cast<size_t>(r)].word = words[static_cast<size_t>(r)];
    std::memcpy(query[static_cast<size_t>(r)].bits.data(), descriptors.ptr<uint8_t>(r), 32);
  }
  std::sort(query.begin(), query.end(),
            [](const Entry& a, const Entry& b) { return a.word < b.word; });
  for (size_t i = 0; i < shortlist.size(); ++i) {
    const int votes = Votes(query, *listed[i]);
    if (votes > 0) {
      candidates.push_back({shortlist[i], static_cast<double>(votes) / descriptors.rows});
    }
  }
  KeepBestCandidates(max_results, &candidates);
  return candidates;
}

}  // namespace sightmap::slam
