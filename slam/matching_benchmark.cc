// Brute-force k-nearest ORB descriptors (the locator's photo-to-place matching: 3,000 photo
// features against a place of ~6,000 keyframe points), run by hand
// (build/slam/matching_benchmark); not a ctest.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "slam/matching.h"

namespace sightmap::slam {
namespace {

cv::Mat RandomDescriptors(int rows, uint64_t seed) {
  cv::Mat descriptors(rows, 32, CV_8U);
  cv::RNG rng(seed);
  rng.fill(descriptors, cv::RNG::UNIFORM, 0, 256);
  return descriptors;
}

// range(2): the kernel (slam::BinaryKernel: 1 AVX-512, 2 AVX2, 3 portable); one this CPU lacks
// is skipped.
void BM_KNearestBinary(benchmark::State& state) {
  const cv::Mat query = RandomDescriptors(static_cast<int>(state.range(0)), 1);
  const cv::Mat reference = RandomDescriptors(static_cast<int>(state.range(1)), 2);
  const auto kernel = static_cast<BinaryKernel>(state.range(2));
  if (!HasKernel(kernel)) {
    state.SkipWithError("this CPU lacks the kernel's instructions");
    return;
  }
  for (auto _ : state) {
    benchmark::DoNotOptimize(KNearestBinary(query, reference, 4, kernel));
  }
  state.counters["pairs/s"] =
      benchmark::Counter(static_cast<double>(state.range(0)) * static_cast<double>(state.range(1)),
                         benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_KNearestBinary)
    ->ArgsProduct({{3000}, {6000}, {1, 2, 3}})
    ->ArgsProduct({{1000}, {1000}, {1, 2, 3}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sightmap::slam

BENCHMARK_MAIN();
