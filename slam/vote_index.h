// Place recognition by descriptor votes: each keyframe's own ORB descriptors kept by visual word
// (Hamming embedding, Jegou et al. 2008, with the descriptor itself as the embedding). A query
// descriptor votes for a keyframe holding a descriptor of the same word within max_hamming bits,
// so two descriptors that merely share a word do not count. A bag of words scores the word
// histograms instead, and a phone photo, seen from elsewhere and at another scale than the walk's
// keyframes, spreads its words over neighbouring ones: on 200 photos against a 1,342-keyframe
// office model, a keyframe within 1.5 m and 30 degrees of the truth ranked among the first 20 for
// 105 of 139 photos that have one when all keyframes were ranked by votes, 100 when the bag of
// words' first 100 were, and 88 by bag-of-words scores alone.
//
// The index re-ranks a shortlist (the bag of words' best) rather than walking posting lists of
// every keyframe: its cost per query is then the shortlist's, whatever the model's size.
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "slam/place_index.h"

namespace sightmap::slam {

class VoteIndex {
 public:
  // Descriptors within this Hamming distance (of 256 bits) of each other vote [bits].
  explicit VoteIndex(int max_hamming = 30);

  // Adds a keyframe's descriptors (CV_8U, 32 columns, one row each) with each row's visual word
  // (Vocabulary::Transform's word_of_row). Throws InvalidArgument on a duplicate id, descriptors
  // that are not ORB's, or a word list of another length.
  void Add(int64_t id, const cv::Mat& descriptors, const std::vector<int>& words);

  bool Contains(int64_t id) const { return keyframes_.count(id) != 0; }
  size_t size() const { return keyframes_.size(); }
  int max_hamming() const { return max_hamming_; }

  // The `shortlist` keyframes ranked by votes, at most `max_results`, most first (ties by smaller
  // id): each query row votes once for every keyframe holding a descriptor of its word within
  // max_hamming. Score is the votes' share of the query's rows, in (0, 1]; keyframes without a
  // vote are left out. Throws InvalidArgument for an id the index does not hold. Thread-safe
  // for concurrent calls on an index nobody adds to.
  std::vector<PlaceCandidate> Rank(const cv::Mat& descriptors, const std::vector<int>& words,
                                   const std::vector<int64_t>& shortlist, int max_results) const;

 private:
  struct Entry {
    int word;
    std::array<uint64_t, 4> bits;
  };
  // Votes for one keyframe from the query's entries; both sorted by word.
  int Votes(const std::vector<Entry>& query, const std::vector<Entry>& keyframe) const;

  int max_hamming_;
  std::unordered_map<int64_t, std::vector<Entry>> keyframes_;  // sorted by word
};

}  // namespace sightmap::slam
