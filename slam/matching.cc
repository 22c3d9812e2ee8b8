#include "slam/matching.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <mutex>

#include <immintrin.h>

#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "slam/hamming.h"

namespace sightmap::slam {
namespace {

constexpr int kNoDistance = std::numeric_limits<int>::max();

// One pass over every (query, reference) pair of 256-bit descriptors gives both directions: each
// query's two nearest references and each reference's nearest query. Not cv::BFMatcher: OpenCV
// 4.6's Hamming kernel enters a trace region for every pair and the cross check needs a second
// pass, which made it 15-20 times slower on 1,000 x 1,000 descriptors. The popcnt clone is chosen
// at load time; the default one serves CPUs without the instruction.
__attribute__((target_clones("popcnt", "default"))) void NearestBinary(
    const uint64_t* query, int num_query, const uint64_t* reference, int num_reference,
    BinaryNeighbours* neighbours) {
  neighbours->best.assign(static_cast<size_t>(num_query), -1);
  neighbours->best_distance.assign(static_cast<size_t>(num_query), kNoDistance);
  neighbours->second_distance.assign(static_cast<size_t>(num_query), kNoDistance);
  neighbours->best_query.assign(static_cast<size_t>(num_reference), -1);
  std::vector<int> best_query_distance(static_cast<size_t>(num_reference), kNoDistance);
  for (int q = 0; q < num_query; ++q) {
    const uint64_t* a = query + 4 * static_cast<size_t>(q);
    TwoNearest nearest;
    for (int r = 0; r < num_reference; ++r) {
      const int distance = Hamming256(a, reference + 4 * static_cast<size_t>(r));
      nearest.Offer(r, distance);
      // Strict, as TwoNearest: the first query of equal distances stays.
      if (distance < best_query_distance[static_cast<size_t>(r)]) {
        best_query_distance[static_cast<size_t>(r)] = distance;
        neighbours->best_query[static_cast<size_t>(r)] = q;
      }
    }
    neighbours->best[static_cast<size_t>(q)] = nearest.best;
    neighbours->best_distance[static_cast<size_t>(q)] = nearest.best_distance;
    neighbours->second_distance[static_cast<size_t>(q)] = nearest.second_distance;
  }
}

// Keeps `d` (of reference `r`) among a query's k nearest, nearest first, by insertion: strict
// comparisons keep the first of equal distances first, as cv::BFMatcher::knnMatch does.
inline void OfferNearest(int r, int d, int k, int* index, int* distance) {
  if (d >= distance[k - 1]) return;
  int j = k - 1;
  for (; j > 0 && d < distance[j - 1]; --j) {
    distance[j] = distance[j - 1];
    index[j] = index[j - 1];
  }
  distance[j] = d;
  index[j] = r;
}

// Each query's k nearest references, nearest first (OfferNearest).
__attribute__((target_clones("popcnt", "default"))) void KNearest(const uint64_t* query,
                                                                  int num_query,
                                                                  const uint64_t* reference,
                                                                  int num_reference, int k,
                                                                  int* indices, int* distances) {
  for (int q = 0; q < num_query; ++q) {
    const uint64_t* a = query + 4 * static_cast<size_t>(q);
    int* index = indices + static_cast<size_t>(q) * static_cast<size_t>(k);
    int* distance = distances + static_cast<size_t>(q) * static_cast<size_t>(k);
    std::fill(index, index + k, -1);
    std::fill(distance, distance + k, kNoDistance);
    for (int r = 0; r < num_reference; ++r) {
      OfferNearest(r, Hamming256(a, reference + 4 * static_cast<size_t>(r)), k, index, distance);
    }
  }
}

// The references' words transposed for the vector kernels: word w of reference r at
// w * stride + r, the stride padded to whole blocks of `block` references (padding all ones;
// the kernels skip it by index).
std::vector<uint64_t> Columns(const uint64_t* reference, int num_reference, size_t block,
                              size_t* stride) {
  *stride = (static_cast<size_t>(num_reference) + block - 1) / block * block;
  std::vector<uint64_t> columns(4 * *stride, ~uint64_t{0});
  for (int r = 0; r < num_reference; ++r) {
    for (size_t w = 0; w < 4; ++w) {
      columns[w * *stride + static_cast<size_t>(r)] = reference[4 * static_cast<size_t>(r) + w];
    }
  }
  return columns;
}

// KNearest with AVX-512's vector popcount, on CPUs that have it (checked at run time): with the
// references' words transposed (Columns), eight references' distances to a query take four
// loads, XORs and popcounts, and one compare skips a block with nothing nearer than the k-th so
// far. 3,000 x 6,000 descriptors (a photo against a place): 21.6 -> 8.1 ms on an AMD EPYC with
// AVX-512 (slam/matching_benchmark.cc).
__attribute__((target("avx512f,avx512vpopcntdq"))) void KNearestAvx512(
    const uint64_t* query, int num_query, const uint64_t* reference, int num_reference, int k,
    int* indices, int* distances) {
  size_t stride = 0;
  const std::vector<uint64_t> columns = Columns(reference, num_reference, 8, &stride);
  alignas(64) uint64_t lanes[8];
  for (int q = 0; q < num_query; ++q) {
    const uint64_t* a = query + 4 * static_cast<size_t>(q);
    const __m512i a0 = _mm512_set1_epi64(static_cast<long long>(a[0]));
    const __m512i a1 = _mm512_set1_epi64(static_cast<long long>(a[1]));
    const __m512i a2 = _mm512_set1_epi64(static_cast<long long>(a[2]));
    const __m512i a3 = _mm512_set1_epi64(static_cast<long long>(a[3]));
    int* index = indices + static_cast<size_t>(q) * static_cast<size_t>(k);
    int* distance = distances + static_cast<size_t>(q) * static_cast<size_t>(k);
    std::fill(index, index + k, -1);
    std::fill(distance, distance + k, kNoDistance);
    for (size_t r = 0; r < stride; r += 8) {
      const __m512i d0 =
          _mm512_popcnt_epi64(_mm512_xor_si512(a0, _mm512_loadu_si512(&columns[0 * stride + r])));
      const __m512i d1 =
          _mm512_popcnt_epi64(_mm512_xor_si512(a1, _mm512_loadu_si512(&columns[1 * stride + r])));
      const __m512i d2 =
          _mm512_popcnt_epi64(_mm512_xor_si512(a2, _mm512_loadu_si512(&columns[2 * stride + r])));
      const __m512i d3 =
          _mm512_popcnt_epi64(_mm512_xor_si512(a3, _mm512_loadu_si512(&columns[3 * stride + r])));
      const __m512i sum = _mm512_add_epi64(_mm512_add_epi64(d0, d1), _mm512_add_epi64(d2, d3));
      // Most blocks hold nothing nearer than the k-th nearest so far: one compare skips them.
      __mmask8 nearer = _mm512_cmplt_epi64_mask(sum, _mm512_set1_epi64(distance[k - 1]));
      if (nearer == 0) continue;
      _mm512_store_si512(lanes, sum);
      for (int lane = 0; lane < 8; ++lane) {
        const int ref = static_cast<int>(r) + lane;
        if (((nearer >> lane) & 1) == 0 || ref >= num_reference) continue;
        OfferNearest(ref, static_cast<int>(lanes[lane]), k, index, distance);
      }
    }
  }
}

// The bits set in each byte of x, by two 16-entry table look-ups (its nibbles).
__attribute__((target("avx2"))) inline __m256i BitsPerByte(__m256i x) {
  const __m256i nibble_bits = _mm256_setr_epi8(0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1,
                                               1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4);
  const __m256i low_nibble = _mm256_set1_epi8(0x0f);
  const __m256i low = _mm256_and_si256(x, low_nibble);
  const __m256i high = _mm256_and_si256(_mm256_srli_epi16(x, 4), low_nibble);
  return _mm256_add_epi8(_mm256_shuffle_epi8(nibble_bits, low),
                         _mm256_shuffle_epi8(nibble_bits, high));
}

// BitsPerByte of one descriptor word XOR four references' same word.
__attribute__((target("avx2"))) inline __m256i WordBits(__m256i query_word,
                                                        const uint64_t* reference_words) {
  return BitsPerByte(_mm256_xor_si256(
      query_word, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(reference_words))));
}

// KNearest for CPUs with AVX2 but not AVX-512's vector popcount (AMD Zen 2 and 3, Intel before
// Ice Lake): the same transposed words, four references a block; the four words' bits per byte
// are added, and one sum of absolute differences against zero adds each reference's 32 byte
// counts into its distance.
__attribute__((target("avx2"))) void KNearestAvx2(const uint64_t* query, int num_query,
                                                  const uint64_t* reference, int num_reference,
                                                  int k, int* indices, int* distances) {
  size_t stride = 0;
  const std::vector<uint64_t> columns = Columns(reference, num_reference, 4, &stride);
  const uint64_t* c0 = columns.data();
  const uint64_t* c1 = c0 + stride;
  const uint64_t* c2 = c1 + stride;
  const uint64_t* c3 = c2 + stride;
  alignas(32) uint64_t lanes[4];
  for (int q = 0; q < num_query; ++q) {
    const uint64_t* a = query + 4 * static_cast<size_t>(q);
    const __m256i a0 = _mm256_set1_epi64x(static_cast<long long>(a[0]));
    const __m256i a1 = _mm256_set1_epi64x(static_cast<long long>(a[1]));
    const __m256i a2 = _mm256_set1_epi64x(static_cast<long long>(a[2]));
    const __m256i a3 = _mm256_set1_epi64x(static_cast<long long>(a[3]));
    int* index = indices + static_cast<size_t>(q) * static_cast<size_t>(k);
    int* distance = distances + static_cast<size_t>(q) * static_cast<size_t>(k);
    std::fill(index, index + k, -1);
    std::fill(distance, distance + k, kNoDistance);
    __m256i kth = _mm256_set1_epi64x(distance[k - 1]);
    for (size_t r = 0; r < stride; r += 4) {
      // At most 4 x 8 bits per byte: the byte sums cannot overflow.
      const __m256i bytes =
          _mm256_add_epi8(_mm256_add_epi8(WordBits(a0, c0 + r), WordBits(a1, c1 + r)),
                          _mm256_add_epi8(WordBits(a2, c2 + r), WordBits(a3, c3 + r)));
      const __m256i sum = _mm256_sad_epu8(bytes, _mm256_setzero_si256());
      // Most blocks hold nothing nearer than the k-th nearest so far: one compare skips them.
      const int nearer = _mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpgt_epi64(kth, sum)));
      if (nearer == 0) continue;
      _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), sum);
      for (int lane = 0; lane < 4; ++lane) {
        const int ref = static_cast<int>(r) + lane;
        if (((nearer >> lane) & 1) == 0 || ref >= num_reference) continue;
        OfferNearest(ref, static_cast<int>(lanes[lane]), k, index, distance);
      }
      kth = _mm256_set1_epi64x(distance[k - 1]);
    }
  }
}

// Descriptor rows of a cv::Mat carry no alignment promise: copied into words once.
std::vector<uint64_t> Words(const cv::Mat& descriptors) {
  std::vector<uint64_t> words(static_cast<size_t>(descriptors.rows) * 4);
  for (int i = 0; i < descriptors.rows; ++i) {
    std::memcpy(&words[4 * static_cast<size_t>(i)], descriptors.ptr<uint8_t>(i), 32);
  }
  return words;
}

std::vector<cv::DMatch> MatchBinary(const cv::Mat& query, const cv::Mat& reference,
                                    const MatchOptions& options) {
  const BinaryNeighbours neighbours = FindBinaryNeighbours(query, reference);
  std::vector<cv::DMatch> matches;
  for (int q = 0; q < query.rows; ++q) {
    const size_t i = static_cast<size_t>(q);
    const int best = neighbours.best[i];
    if (best < 0) continue;
    if (neighbours.best_distance[i] >= options.ratio * neighbours.second_distance[i]) continue;
    if (options.mutual && neighbours.best_query[static_cast<size_t>(best)] != q) continue;
    matches.emplace_back(q, best, static_cast<float>(neighbours.best_distance[i]));
  }
  return matches;
}

// Other lengths and float descriptors.
std::vector<cv::DMatch> MatchWithOpenCv(const cv::Mat& query, const cv::Mat& reference,
                                        const MatchOptions& options) {
  cv::BFMatcher matcher(query.type() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, reference, knn, 2);
  std::vector<int> best_query_for_reference;
  if (options.mutual) {
    std::vector<cv::DMatch> backward;
    matcher.match(reference, query, backward);
    best_query_for_reference.assign(static_cast<size_t>(reference.rows), -1);
    for (const cv::DMatch& match : backward) {
      best_query_for_reference[static_cast<size_t>(match.queryIdx)] = match.trainIdx;
    }
  }
  std::vector<cv::DMatch> matches;
  for (const std::vector<cv::DMatch>& pair : knn) {
    if (pair.size() < 2) continue;
    if (pair[0].distance >= options.ratio * pair[1].distance) continue;
    if (options.mutual &&
        best_query_for_reference[static_cast<size_t>(pair[0].trainIdx)] != pair[0].queryIdx) {
      continue;
    }
    matches.push_back(pair[0]);
  }
  return matches;
}

}  // namespace

bool MatchOptions::Check(std::string* error) const {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    if (error) *error = "ratio must be in (0, 1]";
    return false;
  }
  return true;
}

BinaryNeighbours FindBinaryNeighbours(const cv::Mat& query, const cv::Mat& reference) {
  SIGHTMAP_CHECK(query.type() == CV_8U && reference.type() == CV_8U &&
                     (query.empty() || query.cols == 32) &&
                     (reference.empty() || reference.cols == 32),
                 "binary neighbours need 256-bit (32-byte) descriptors");
  BinaryNeighbours neighbours;
  const std::vector<uint64_t> query_words = Words(query);
  const std::vector<uint64_t> reference_words = Words(reference);
  NearestBinary(query_words.data(), query.rows, reference_words.data(), reference.rows,
                &neighbours);
  return neighbours;
}

bool HasKernel(BinaryKernel kernel) {
  switch (kernel) {
    case BinaryKernel::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vpopcntdq");
    case BinaryKernel::kAvx2:
      return __builtin_cpu_supports("avx2");
    case BinaryKernel::kFastest:
    case BinaryKernel::kPortable:
      return true;
  }
  return false;
}

BinaryKernel FastestKernel() {
  if (HasKernel(BinaryKernel::kAvx512)) return BinaryKernel::kAvx512;
  if (HasKernel(BinaryKernel::kAvx2)) return BinaryKernel::kAvx2;
  return BinaryKernel::kPortable;
}

std::vector<std::vector<cv::DMatch>> KNearestBinary(const cv::Mat& query, const cv::Mat& reference,
                                                    int k, BinaryKernel kernel) {
  SIGHTMAP_CHECK(k >= 1, "k nearest needs k >= 1");
  SIGHTMAP_CHECK(HasKernel(kernel),
                 "this CPU lacks the instructions of the k-nearest kernel asked for");
  if (kernel == BinaryKernel::kFastest) kernel = FastestKernel();
  SIGHTMAP_CHECK(query.type() == CV_8U && reference.type() == CV_8U &&
                     (query.empty() || query.cols == 32) &&
                     (reference.empty() || reference.cols == 32),
                 "k nearest needs 256-bit (32-byte) descriptors");
  const size_t slots = static_cast<size_t>(query.rows) * static_cast<size_t>(k);
  std::vector<int> indices(slots);
  std::vector<int> distances(slots);
  const std::vector<uint64_t> query_words = Words(query);
  const std::vector<uint64_t> reference_words = Words(reference);
  if (kernel == BinaryKernel::kAvx512) {
    KNearestAvx512(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
                   indices.data(), distances.data());
  } else if (kernel == BinaryKernel::kAvx2) {
    KNearestAvx2(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
                 indices.data(), distances.data());
  } else {
    KNearest(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
             indices.data(), distances.data());
  }
  std::vector<std::vector<cv::DMatch>> knn(static_cast<size_t>(query.rows));
  for (int q = 0; q < query.rows; ++q) {
    std::vector<cv::DMatch>& neighbours = knn[static_cast<size_t>(q)];
    for (int j = 0; j < k; ++j) {
      const size_t slot = static_cast<size_t>(q) * static_cast<size_t>(k) + static_cast<size_t>(j);
      if (indices[slot] < 0) break;
      neighbours.emplace_back(q, indices[slot], static_cast<float>(distances[slot]));
    }
  }
  return knn;
}

std::vector<std::vector<cv::DMatch>> KNearestEuclidean(const cv::Mat& query,
                                                       const cv::Mat& reference, int k) {
  SIGHTMAP_CHECK(k >= 1, "k nearest needs k >= 1");
  SIGHTMAP_CHECK((query.type() == CV_8U || query.type() == CV_32F) &&
                     query.type() == reference.type() &&
                     (query.empty() || reference.empty() || query.cols == reference.cols),
                 "Euclidean k nearest needs byte or float rows of one width");
  std::vector<std::vector<cv::DMatch>> knn(static_cast<size_t>(query.rows));
  if (query.empty() || reference.empty()) return knn;
  cv::Mat query_f;
  cv::Mat reference_f;
  query.convertTo(query_f, CV_32F);
  reference.convertTo(reference_f, CV_32F);
  const double pairs = static_cast<double>(query.rows) * reference.rows;
  if (pairs <= kExactEuclideanPairs) {
    knn.clear();  // knnMatch appends
    cv::BFMatcher(cv::NORM_L2).knnMatch(query_f, reference_f, knn, k);
    return knn;
  }
  const int kk = std::min(k, reference.rows);
  cv::Mat indices(query.rows, kk, CV_32S);
  cv::Mat distances_sq(query.rows, kk, CV_32F);
  cv::flann::Index index;
  {
    // FLANN's kd-trees split on dimensions drawn with std::rand: seeded under a lock so that one
    // input always gives one answer.
    static std::mutex seed_mutex;
    std::lock_guard<std::mutex> lock(seed_mutex);
    cvflann::seed_random(7);
    index.build(reference_f, cv::flann::KDTreeIndexParams(4));
  }
  index.knnSearch(query_f, indices, distances_sq, kk, cv::flann::SearchParams(64));
  for (int q = 0; q < query.rows; ++q) {
    std::vector<cv::DMatch>& neighbours = knn[static_cast<size_t>(q)];
    for (int j = 0; j < kk; ++j) {
      const int r = indices.at<int>(q, j);
      if (r < 0 || r >= reference.rows) break;
      neighbours.emplace_back(q, r, std::sqrt(distances_sq.at<float>(q, j)));
    }
  }
  return knn;
}

std::vector<cv::DMatch> MatchDescriptors(const cv::Mat& query, const cv::Mat& reference,
                                         const MatchOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  if (query.empty() || reference.rows < 2) return {};
  SIGHTMAP_CHECK(query.type() == reference.type() && query.cols == reference.cols,
                 "cannot match descriptors of different types or lengths");
  if (query.type() == CV_8U && query.cols == 32) return MatchBinary(query, reference, options);
  return MatchWithOpenCv(query, reference, options);
}

SIGHTMAP_OPTIONS_JSON(MatchOptions, ratio, mutual)

}  // namespace sightmap::slam
