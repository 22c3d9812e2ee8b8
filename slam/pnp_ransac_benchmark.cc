// PnP RANSAC: slam::SolvePnpRansac against OpenCV's solvePnPRansac (AP3P), the same samples drawn.
// Run by hand: build/slam/pnp_ransac_benchmark. Compare the two within one run (the ratio), not
// across machines. Cases as the locator meets them: a place whose pose is found (300 matches, 35%
// inliers) and one without (150 matches, none consistent: all 500 samples drawn).
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/calib3d.hpp>

#include "slam/pnp_ransac.h"

namespace sightmap::slam {
namespace {

const cv::Matx33d kCamera(525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0);

struct Correspondences {
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
};

// `count` points 1-8 m before an identity camera, the first `inliers` projected with 0.8 px of
// noise, the others at random pixels.
Correspondences Make(int count, int inliers) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.8);
  Correspondences c;
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 + 3.5 * (unit(rng) + 1.0);
    const double x = unit(rng) * 320.0 / 525.0 * z;
    const double y = unit(rng) * 240.0 / 525.0 * z;
    c.object.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    if (i < inliers) {
      c.image.emplace_back(static_cast<float>(525.0 * x / z + 319.5 + noise(rng)),
                           static_cast<float>(525.0 * y / z + 239.5 + noise(rng)));
    } else {
      c.image.emplace_back(static_cast<float>(320.0 + 320.0 * unit(rng)),
                           static_cast<float>(240.0 + 240.0 * unit(rng)));
    }
  }
  return c;
}

void Ours(benchmark::State& state) {
  const Correspondences c =
      Make(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const PnpRansacOptions options;
  for (auto _ : state) {
    benchmark::DoNotOptimize(SolvePnpRansac(c.object, c.image, kCamera, options));
  }
}

void OpenCv(benchmark::State& state) {
  const Correspondences c =
      Make(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const PnpRansacOptions options;
  for (auto _ : state) {
    cv::Vec3d rvec;
    cv::Vec3d tvec;
    std::vector<int> inliers;
    benchmark::DoNotOptimize(cv::solvePnPRansac(c.object, c.image, kCamera, cv::noArray(), rvec,
                                                tvec, false, options.max_iterations,
                                                static_cast<float>(options.reprojection_px),
                                                options.confidence, inliers, cv::SOLVEPNP_AP3P));
  }
}

BENCHMARK(Ours)->Args({300, 105})->Args({150, 0})->Unit(benchmark::kMillisecond);
BENCHMARK(OpenCv)->Args({300, 105})->Args({150, 0})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sightmap::slam

BENCHMARK_MAIN();
