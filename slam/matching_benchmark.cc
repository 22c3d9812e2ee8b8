// Brute-force k-nearest ORB descriptors (the locator's photo-to-place matching: 3,000 photo
// features against a place of ~6,000 keyframe points) and RootSIFT rows, run by hand
// (build/slam/matching_benchmark); not a ctest.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "slam/matching.h"

namespace sightmap::slam {
namespace {

// `rows` random byte rows of `cols` bytes, each byte below `below`.
cv::Mat RandomRows(int rows, int cols, int below, uint64_t seed) {
  cv::Mat descriptors(rows, cols, CV_8U);
  cv::RNG rng(seed);
  rng.fill(descriptors, cv::RNG::UNIFORM, 0, below);
  return descriptors;
}

// Times `knn(query, reference, k = 4, kernel)` on state.range(0) x state.range(1) rows; range(2)
// is the kernel (slam::MatchKernel: 1 AVX-512, 2 AVX2, 3 portable), skipped where the CPU lacks it.
template <typename Knn>
void TimeKNearest(benchmark::State& state, const cv::Mat& query, const cv::Mat& reference,
                  Knn knn) {
  const auto kernel = static_cast<MatchKernel>(state.range(2));
  if (!HasKernel(kernel)) {
    state.SkipWithError("this CPU lacks the kernel's instructions");
    return;
  }
  for (auto _ : state) {
    benchmark::DoNotOptimize(knn(query, reference, 4, kernel));
  }
  state.counters["pairs/s"] =
      benchmark::Counter(static_cast<double>(query.rows) * static_cast<double>(reference.rows),
                         benchmark::Counter::kIsIterationInvariantRate);
}

void BM_KNearestBinary(benchmark::State& state) {
  TimeKNearest(state, RandomRows(static_cast<int>(state.range(0)), 32, 256, 1),
               RandomRows(static_cast<int>(state.range(1)), 32, 256, 2), KNearestBinary);
}
BENCHMARK(BM_KNearestBinary)
    ->ArgsProduct({{3000}, {6000}, {1, 2, 3}})
    ->ArgsProduct({{1000}, {1000}, {1, 2, 3}})
    ->Unit(benchmark::kMillisecond);

// RootSIFT-sized byte rows (128 bytes): the second look's photo against a place (the survey's
// median call: 430 x 1,170; its largest: 700 x 7,800). Only AVX2 (2) and portable (3) kernels.
void BM_KNearestEuclideanBytes(benchmark::State& state) {
  TimeKNearest(state, RandomRows(static_cast<int>(state.range(0)), 128, 64, 3),
               RandomRows(static_cast<int>(state.range(1)), 128, 64, 4), KNearestEuclidean);
}
BENCHMARK(BM_KNearestEuclideanBytes)
    ->ArgsProduct({{430}, {1170}, {2, 3}})
    ->ArgsProduct({{700}, {7800}, {2, 3}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sightmap::slam

BENCHMARK_MAIN();
