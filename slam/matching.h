// Descriptor matching with the nearest-neighbour distance ratio test (Lowe), the paper's matcher.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

namespace sightmap::slam {

struct MatchOptions {
  // A match is kept when its distance is below ratio x the second-nearest distance.
  // 0.9 rather than Lowe's 0.8: at 1 Hz, frames 30 deg apart with motion blur keep too few matches
  // at 0.8 (measured on the simulator's walk: 20 of 29 consecutive pairs registered at 0.9, 18 at
  // 0.8); RANSAC and the dense check reject what the looser test lets in.
  double ratio = 0.9;
  // Also require the query to be the reference's nearest neighbour (cross check).
  bool mutual = true;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const MatchOptions& options);
void from_json(const nlohmann::json& json, MatchOptions& options);

// For every query descriptor its nearest and second-nearest reference, and for every reference
// its nearest query, by Hamming distance (256-bit descriptors: ORB); the first of equal distances
// wins. The ratio test and the cross check of MatchDescriptors read these.
struct BinaryNeighbours {
  std::vector<int> best;             // per query: index into reference, -1 if there is none
  std::vector<int> best_distance;    // per query [bits]; INT_MAX if there is none
  std::vector<int> second_distance;  // per query [bits]; INT_MAX with fewer than two references
  std::vector<int> best_query;       // per reference: index into query, -1 if there is none
};
BinaryNeighbours FindBinaryNeighbours(const cv::Mat& query, const cv::Mat& reference);

// The k-nearest kernels, which give the same lists. kFastest: the first of the others this CPU
// runs (checked at run time); tests and benchmarks name one to compare them.
enum class MatchKernel {
  kFastest,
  // Hamming: AVX-512's vector popcount (AMD Zen 4, Intel Ice Lake and later); Euclidean: AVX2's.
  kAvx512,
  // Hamming: nibble table look-ups; Euclidean: 16-bit differences squared and added in pairs,
  // for rows of a multiple of 16 bytes (others run the portable kernel). AMD Zen 2 and later,
  // Intel Haswell and later.
  kAvx2,
  // Hamming: the popcount instruction where there is one, else bit arithmetic; Euclidean: SSE2,
  // one pair of rows at a time.
  kPortable,
};
// Whether this CPU runs `kernel`.
bool HasKernel(MatchKernel kernel);
// The kernel kFastest picks on this CPU, and a kernel's name ("avx512", "avx2", "portable",
// "fastest"): timings are only comparable between runs on the same kernel.
MatchKernel FastestKernel();
std::string KernelName(MatchKernel kernel);

// For every query descriptor its k nearest references by Hamming distance (256-bit descriptors),
// nearest first; fewer when the reference has fewer rows. The same lists, in the same order, as
// cv::BFMatcher(cv::NORM_HAMMING).knnMatch, at a tenth of its time or less. On 3,000 x 6,000
// descriptors (slam/matching_benchmark.cc) the AVX-512 kernel takes 2.7x less time than the
// portable one on an AMD Zen 4, the AVX2 kernel 1.5x less on a Zen 3 (22 against 34 ms). Throws
// for a kernel this CPU lacks.
std::vector<std::vector<cv::DMatch>> KNearestBinary(const cv::Mat& query, const cv::Mat& reference,
                                                    int k,
                                                    MatchKernel kernel = MatchKernel::kFastest);

// For every query descriptor its k nearest references by Euclidean distance (equal-width byte or
// float rows: RootSIFT), nearest first; fewer when the reference has fewer rows. Distances in the
// rows' own units. Byte rows are compared exactly, by integer sums of squares (the same lists as
// cv::BFMatcher(cv::NORM_L2).knnMatch of the rows as floats, ties included; `kernel` as for
// KNearestBinary). Float rows: exact up to kExactEuclideanPairs query x reference pairs,
// approximate above (randomised kd-trees, seeded, so the same input gives the same answer).
inline constexpr double kExactEuclideanPairs = 4e6;
std::vector<std::vector<cv::DMatch>> KNearestEuclidean(const cv::Mat& query,
                                                       const cv::Mat& reference, int k,
                                                       MatchKernel kernel = MatchKernel::kFastest);

// Matches query descriptors to reference descriptors (both CV_8U binary, or both CV_32F).
// DMatch::queryIdx indexes `query`, trainIdx indexes `reference`.
std::vector<cv::DMatch> MatchDescriptors(const cv::Mat& query, const cv::Mat& reference,
                                         const MatchOptions& options = MatchOptions());

}  // namespace sightmap::slam
