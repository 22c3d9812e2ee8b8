#include "slam/vote_index.h"

#include <algorithm>

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

std::vector<VoteIndex::Entry> VoteIndex::SortedEntries(const std::vector<int>& words) {
  std::vector<Entry> entries(words.size());
  for (size_t r = 0; r < words.size(); ++r) entries[r] = {words[r], static_cast<int>(r)};
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& a, const Entry& b) { return a.word < b.word; });
  return entries;
}

void VoteIndex::Add(int64_t id, const cv::Mat& descriptors, const std::vector<int>& words) {
  if (Contains(id)) SIGHTMAP_THROW(InvalidArgument, "VoteIndex already holds keyframe " << id);
  CheckRows(descriptors, words, "a keyframe's");
  keyframes_.emplace(id, Keyframe{descriptors, SortedEntries(words)});
}

int VoteIndex::Votes(const cv::Mat& query, const std::vector<Entry>& query_entries,
                     const Keyframe& keyframe) const {
  const std::vector<Entry>& entries = keyframe.entries;
  int votes = 0;
  size_t q = 0;
  size_t k = 0;
  while (q < query_entries.size() && k < entries.size()) {
    if (query_entries[q].word < entries[k].word) {
      ++q;
    } else if (entries[k].word < query_entries[q].word) {
      ++k;
    } else {
      const int word = query_entries[q].word;
      size_t k_end = k;
      while (k_end < entries.size() && entries[k_end].word == word) ++k_end;
      // Each query row of the word votes once, however many of the keyframe's descriptors (a
      // repeated texture) lie within reach.
      for (; q < query_entries.size() && query_entries[q].word == word; ++q) {
        const uint8_t* bits = query.ptr<uint8_t>(query_entries[q].row);
        for (size_t j = k; j < k_end; ++j) {
          if (Hamming256(bits, keyframe.descriptors.ptr<uint8_t>(entries[j].row)) <= max_hamming_) {
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
  std::vector<const Keyframe*> listed;
  for (int64_t id : shortlist) {
    const auto found = keyframes_.find(id);
    if (found == keyframes_.end())
      SIGHTMAP_THROW(InvalidArgument, "VoteIndex holds no keyframe " << id);
    listed.push_back(&found->second);
  }
  std::vector<PlaceCandidate> candidates;
  if (max_results <= 0 || descriptors.rows == 0) return candidates;
  const std::vector<Entry> query = SortedEntries(words);
  for (size_t i = 0; i < shortlist.size(); ++i) {
    const int votes = Votes(descriptors, query, *listed[i]);
    if (votes > 0) {
      candidates.push_back({shortlist[i], static_cast<double>(votes) / descriptors.rows});
    }
  }
  KeepBestCandidates(max_results, &candidates);
  return candidates;
}

}  // namespace sightmap::slam
