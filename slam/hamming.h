// Hamming distance between 256-bit binary descriptors (ORB), by popcount: the vocabulary's tree
// search and registration's guided matching compare millions of pairs.
#pragma once

#include <cstdint>
#include <cstring>
#include <limits>

namespace sightmap::slam {

inline int Hamming256(const uint64_t* a, const uint64_t* b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

// Descriptor rows of a cv::Mat carry no alignment promise: copied into words first.
inline int Hamming256(const uint8_t* a, const uint8_t* b) {
  uint64_t wa[4];
  uint64_t wb[4];
  std::memcpy(wa, a, sizeof(wa));
  std::memcpy(wb, b, sizeof(wb));
  return Hamming256(wa, wb);
}

// The nearest and second-nearest of a stream of candidates, for the ratio test. Strict
// comparisons keep the first of equal distances, as cv::BFMatcher does.
struct TwoNearest {
  int best = -1;  // index of the nearest offered candidate; -1 before the first
  int best_distance = std::numeric_limits<int>::max();
  int second_distance = std::numeric_limits<int>::max();

  void Offer(int index, int distance) {
    if (distance < best_distance) {
      second_distance = best_distance;
      best_distance = distance;
      best = index;
    } else if (distance < second_distance) {
      second_distance = distance;
    }
  }
};

}  // namespace sightmap::slam
