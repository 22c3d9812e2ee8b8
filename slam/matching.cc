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

// One query's k nearest references so far: its k slots of a kernel's output arrays, emptied on
// construction (index -1, distance kNoDistance), nearest first.
struct NearestSlots {
  NearestSlots(int q, int num_nearest, int* indices, int* distances)
      : k(num_nearest),
        index(indices + static_cast<size_t>(q) * static_cast<size_t>(num_nearest)),
        distance(distances + static_cast<size_t>(q) * static_cast<size_t>(num_nearest)) {
    std::fill(index, index + k, -1);
    std::fill(distance, distance + k, kNoDistance);
  }
  int Kth() const { return distance[k - 1]; }
  void Offer(int r, int d) { OfferNearest(r, d, k, index, distance); }
  // A vector kernel's block of `count` references from `first`: offers the lanes the bit mask
  // `nearer` marks, skipping the padding past num_reference.
  template <typename Lane>
  void OfferLanes(int first, const Lane* lanes, int count, int nearer, int num_reference) {
    for (int lane = 0; lane < count; ++lane) {
      const int ref = first + lane;
      if (((nearer >> lane) & 1) == 0 || ref >= num_reference) continue;
      Offer(ref, static_cast<int>(lanes[lane]));
    }
  }

  int k;
  int* index;
  int* distance;
};

// Each query's k nearest references, nearest first (OfferNearest).
__attribute__((target_clones("popcnt", "default"))) void KNearest(const uint64_t* query,
                                                                  int num_query,
                                                                  const uint64_t* reference,
                                                                  int num_reference, int k,
                                                                  int* indices, int* distances) {
  for (int q = 0; q < num_query; ++q) {
    const uint64_t* a = query + 4 * static_cast<size_t>(q);
    NearestSlots nearest(q, k, indices, distances);
    for (int r = 0; r < num_reference; ++r) {
      nearest.Offer(r, Hamming256(a, reference + 4 * static_cast<size_t>(r)));
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
    NearestSlots nearest(q, k, indices, distances);
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
      __mmask8 nearer = _mm512_cmplt_epi64_mask(sum, _mm512_set1_epi64(nearest.Kth()));
      if (nearer == 0) continue;
      _mm512_store_si512(lanes, sum);
      nearest.OfferLanes(static_cast<int>(r), lanes, 8, nearer, num_reference);
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
    NearestSlots nearest(q, k, indices, distances);
    __m256i kth = _mm256_set1_epi64x(nearest.Kth());
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
      nearest.OfferLanes(static_cast<int>(r), lanes, 4, nearer, num_reference);
      kth = _mm256_set1_epi64x(nearest.Kth());
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

// Per query the k slots the kernels filled (-1: none), as cv::DMatch lists with `to_distance`
// of each kernel distance.
template <typename ToDistance>
std::vector<std::vector<cv::DMatch>> ToDMatches(int num_query, int k,
                                                const std::vector<int>& indices,
                                                const std::vector<int>& distances,
                                                ToDistance to_distance) {
  std::vector<std::vector<cv::DMatch>> knn(static_cast<size_t>(num_query));
  for (int q = 0; q < num_query; ++q) {
    std::vector<cv::DMatch>& neighbours = knn[static_cast<size_t>(q)];
    for (int j = 0; j < k; ++j) {
      const size_t slot = static_cast<size_t>(q) * static_cast<size_t>(k) + static_cast<size_t>(j);
      if (indices[slot] < 0) break;
      neighbours.emplace_back(q, indices[slot], to_distance(distances[slot]));
    }
  }
  return knn;
}

// Sum of squared differences of two byte rows of `cols` bytes: 16 bytes a step with SSE2 (every
// x86-64 CPU has it), widened to 16-bit and squared and added in pairs; the rest byte by byte.
int SquaredDistance(const uint8_t* a, const uint8_t* b, int cols) {
  const __m128i zero = _mm_setzero_si128();
  __m128i sums = zero;
  int c = 0;
  for (; c + 16 <= cols; c += 16) {
    const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + c));
    const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + c));
    const __m128i low = _mm_sub_epi16(_mm_unpacklo_epi8(va, zero), _mm_unpacklo_epi8(vb, zero));
    const __m128i high = _mm_sub_epi16(_mm_unpackhi_epi8(va, zero), _mm_unpackhi_epi8(vb, zero));
    sums = _mm_add_epi32(sums, _mm_add_epi32(_mm_madd_epi16(low, low), _mm_madd_epi16(high, high)));
  }
  alignas(16) int lanes[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes), sums);
  int sum = lanes[0] + lanes[1] + lanes[2] + lanes[3];
  for (; c < cols; ++c) {
    const int d = static_cast<int>(a[c]) - static_cast<int>(b[c]);
    sum += d * d;
  }
  return sum;
}

// Each byte query row's k nearest byte reference rows by squared distance (OfferNearest).
void KNearestBytes(const cv::Mat& query, const cv::Mat& reference, int k, int* indices,
                   int* distances) {
  for (int q = 0; q < query.rows; ++q) {
    NearestSlots nearest(q, k, indices, distances);
    const uint8_t* a = query.ptr<uint8_t>(q);
    for (int r = 0; r < reference.rows; ++r) {
      nearest.Offer(r, SquaredDistance(a, reference.ptr<uint8_t>(r), query.cols));
    }
  }
}

// Squared differences of a query's 16 bytes (as 16-bit) and a reference's, added in pairs into
// eight 32-bit sums: at most 2 x 255^2 each, no overflow.
__attribute__((target("avx2"))) inline __m256i AddSquaredDifferences(__m256i sums,
                                                                     __m256i query_words,
                                                                     const uint8_t* reference) {
  const __m256i r =
      _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(reference)));
  const __m256i d = _mm256_sub_epi16(query_words, r);
  return _mm256_add_epi32(sums, _mm256_madd_epi16(d, d));
}

// KNearestBytes for rows of a multiple of 16 bytes (RootSIFT's 128), on CPUs with AVX2: the query
// row widened to 16-bit once, four references a block, their eight partial sums each reduced
// together by three horizontal adds, and one compare skips a block with nothing nearer than the
// k-th so far.
__attribute__((target("avx2"))) void KNearestBytesAvx2(const cv::Mat& query,
                                                       const cv::Mat& reference, int k,
                                                       int* indices, int* distances) {
  const int chunks = query.cols / 16;
  std::vector<int16_t> widened(static_cast<size_t>(query.cols));
  const int blocks = reference.rows / 4;
  for (int q = 0; q < query.rows; ++q) {
    const uint8_t* a = query.ptr<uint8_t>(q);
    std::copy(a, a + query.cols, widened.begin());
    NearestSlots nearest(q, k, indices, distances);
    alignas(16) int lanes[4];
    for (int block = 0; block < blocks; ++block) {
      const int r = 4 * block;
      const uint8_t* b0 = reference.ptr<uint8_t>(r);
      const uint8_t* b1 = reference.ptr<uint8_t>(r + 1);
      const uint8_t* b2 = reference.ptr<uint8_t>(r + 2);
      const uint8_t* b3 = reference.ptr<uint8_t>(r + 3);
      __m256i s0 = _mm256_setzero_si256();
      __m256i s1 = _mm256_setzero_si256();
      __m256i s2 = _mm256_setzero_si256();
      __m256i s3 = _mm256_setzero_si256();
      for (int c = 0; c < chunks; ++c) {
        const __m256i w = _mm256_loadu_si256(
            reinterpret_cast<const __m256i*>(&widened[16 * static_cast<size_t>(c)]));
        s0 = AddSquaredDifferences(s0, w, b0 + 16 * c);
        s1 = AddSquaredDifferences(s1, w, b1 + 16 * c);
        s2 = AddSquaredDifferences(s2, w, b2 + 16 * c);
        s3 = AddSquaredDifferences(s3, w, b3 + 16 * c);
      }
      // Per 128-bit half: [sum s0, sum s1, sum s2, sum s3] of that half's four lanes each.
      const __m256i halves =
          _mm256_hadd_epi32(_mm256_hadd_epi32(s0, s1), _mm256_hadd_epi32(s2, s3));
      const __m128i sums =
          _mm_add_epi32(_mm256_castsi256_si128(halves), _mm256_extracti128_si256(halves, 1));
      const int nearer =
          _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_set1_epi32(nearest.Kth()), sums)));
      if (nearer == 0) continue;
      _mm_store_si128(reinterpret_cast<__m128i*>(lanes), sums);
      nearest.OfferLanes(r, lanes, 4, nearer, reference.rows);
    }
    for (int r = 4 * blocks; r < reference.rows; ++r) {
      nearest.Offer(r, SquaredDistance(a, reference.ptr<uint8_t>(r), query.cols));
    }
  }
}

// The k nearest of byte rows, exactly, as cv::DMatch lists with Euclidean distances computed as
// cv::BFMatcher does (the float square root of the sum).
std::vector<std::vector<cv::DMatch>> KNearestEuclideanBytes(const cv::Mat& query,
                                                            const cv::Mat& reference, int k,
                                                            MatchKernel kernel) {
  const size_t slots = static_cast<size_t>(query.rows) * static_cast<size_t>(k);
  std::vector<int> indices(slots);
  std::vector<int> distances(slots);
  if (kernel != MatchKernel::kPortable && query.cols % 16 == 0 && HasKernel(MatchKernel::kAvx2)) {
    KNearestBytesAvx2(query, reference, k, indices.data(), distances.data());
  } else {
    KNearestBytes(query, reference, k, indices.data(), distances.data());
  }
  return ToDMatches(query.rows, k, indices, distances,
                    [](int d) { return std::sqrt(static_cast<float>(d)); });
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

bool HasKernel(MatchKernel kernel) {
  switch (kernel) {
    case MatchKernel::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vpopcntdq");
    case MatchKernel::kAvx2:
      return __builtin_cpu_supports("avx2");
    case MatchKernel::kFastest:
    case MatchKernel::kPortable:
      return true;
  }
  return false;
}

MatchKernel FastestKernel() {
  if (HasKernel(MatchKernel::kAvx512)) return MatchKernel::kAvx512;
  if (HasKernel(MatchKernel::kAvx2)) return MatchKernel::kAvx2;
  return MatchKernel::kPortable;
}

std::string KernelName(MatchKernel kernel) {
  switch (kernel) {
    case MatchKernel::kFastest:
      return "fastest";
    case MatchKernel::kAvx512:
      return "avx512";
    case MatchKernel::kAvx2:
      return "avx2";
    case MatchKernel::kPortable:
      return "portable";
  }
  return "unknown";
}

std::vector<std::vector<cv::DMatch>> KNearestBinary(const cv::Mat& query, const cv::Mat& reference,
                                                    int k, MatchKernel kernel) {
  SIGHTMAP_CHECK(k >= 1, "k nearest needs k >= 1");
  SIGHTMAP_CHECK(HasKernel(kernel),
                 "this CPU lacks the instructions of the k-nearest kernel asked for");
  if (kernel == MatchKernel::kFastest) kernel = FastestKernel();
  SIGHTMAP_CHECK(query.type() == CV_8U && reference.type() == CV_8U &&
                     (query.empty() || query.cols == 32) &&
                     (reference.empty() || reference.cols == 32),
                 "k nearest needs 256-bit (32-byte) descriptors");
  const size_t slots = static_cast<size_t>(query.rows) * static_cast<size_t>(k);
  std::vector<int> indices(slots);
  std::vector<int> distances(slots);
  const std::vector<uint64_t> query_words = Words(query);
  const std::vector<uint64_t> reference_words = Words(reference);
  if (kernel == MatchKernel::kAvx512) {
    KNearestAvx512(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
                   indices.data(), distances.data());
  } else if (kernel == MatchKernel::kAvx2) {
    KNearestAvx2(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
                 indices.data(), distances.data());
  } else {
    KNearest(query_words.data(), query.rows, reference_words.data(), reference.rows, k,
             indices.data(), distances.data());
  }
  return ToDMatches(query.rows, k, indices, distances, [](int d) { return static_cast<float>(d); });
}

std::vector<std::vector<cv::DMatch>> KNearestEuclidean(const cv::Mat& query,
                                                       const cv::Mat& reference, int k,
                                                       MatchKernel kernel) {
  SIGHTMAP_CHECK(k >= 1, "k nearest needs k >= 1");
  SIGHTMAP_CHECK((query.type() == CV_8U || query.type() == CV_32F) &&
                     query.type() == reference.type() &&
                     (query.empty() || reference.empty() || query.cols == reference.cols),
                 "Euclidean k nearest needs byte or float rows of one width");
  std::vector<std::vector<cv::DMatch>> knn(static_cast<size_t>(query.rows));
  if (query.empty() || reference.empty()) return knn;
  SIGHTMAP_CHECK(HasKernel(kernel),
                 "this CPU lacks the instructions of the k-nearest kernel asked for");
  if (query.type() == CV_8U) return KNearestEuclideanBytes(query, reference, k, kernel);
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
