// Time of one off-screen render of a 1, 5 and 10 million point map (1280x720: floor plan and
// follow view, status overlay, read-back), run by hand, not by ctest:
//   render_benchmark [--benchmark_filter=...]
// Variants: point size 1 and 2, with and without the floor plan's depth cue (fog), the follow
// view alone, and the upload (Sync) of the whole map.
#include <random>

#include <benchmark/benchmark.h>

#include "render/map_renderer.h"
#include "render/offscreen_context.h"

namespace sightmap::render {
namespace {

constexpr int kWidth = 1280;
constexpr int kHeight = 720;
constexpr int kPointsPerKeyframe = 10000;

// Keyframes walking through a 24 x 16 m floor, each seeing points up to 4 m ahead.
MapScene MakeScene(int64_t points) {
  MapScene scene;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  MapUpdate update;
  const int64_t keyframes = points / kPointsPerKeyframe;
  for (int64_t i = 0; i < keyframes; ++i) {
    MapKeyframe keyframe;
    keyframe.id = i;
    keyframe.session = 1 + static_cast<int>(i % 2);
    const double t = static_cast<double>(i) / static_cast<double>(keyframes);
    Eigen::Matrix3d r;
    r.col(0) = Eigen::Vector3d(0, -1, 0);
    r.col(1) = Eigen::Vector3d(0, 0, -1);
    r.col(2) = Eigen::Vector3d(1, 0, 0);
    keyframe.world_from_cam.linear() =
        Eigen::AngleAxisd(6.28 * t * 3, Eigen::Vector3d::UnitZ()).toRotationMatrix() * r;
    keyframe.world_from_cam.translation() =
        Eigen::Vector3d(12 + 9 * std::cos(6.28 * t), 8 + 5 * std::sin(6.28 * t), 1.4);
    keyframe.points_cam.resize(kPointsPerKeyframe);
    keyframe.colors.resize(kPointsPerKeyframe);
    for (int j = 0; j < kPointsPerKeyframe; ++j) {
      const float z = 0.5f + 3.5f * unit(rng);
      keyframe.points_cam[static_cast<size_t>(j)] =
          Eigen::Vector3f((unit(rng) - 0.5f) * 1.1f * z, (unit(rng) - 0.5f) * 0.8f * z, z);
      keyframe.colors[static_cast<size_t>(j)] = {static_cast<uint8_t>(unit(rng) * 255),
                                                 static_cast<uint8_t>(unit(rng) * 255), 128};
    }
    update.keyframes.push_back(std::move(keyframe));
  }
  update.camera = update.keyframes.back().world_from_cam;
  scene.Apply(std::move(update));
  return scene;
}

const MapScene& SceneOf(int64_t millions) {
  static std::map<int64_t, MapScene> scenes;
  auto it = scenes.find(millions);
  if (it == scenes.end()) it = scenes.emplace(millions, MakeScene(millions * 1000000)).first;
  return it->second;
}

enum Variant {
  kFull = 0,
  kFullPointSize1 = 1,
  kFullNoDepthCue = 2,
  kFollowOnly = 3,
  kFullAllPoints = 4,  // no level of detail
  kFullHalfPointPerPixel = 5,
  kEmptyFrame = 6,  // clear, status text and read-back only
};

void BM_Render(benchmark::State& state) {
  const int64_t millions = state.range(0);
  const Variant variant = static_cast<Variant>(state.range(1));
  const MapScene& scene = SceneOf(millions);
  MapRenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  if (variant == kFullPointSize1) options.point_size_px = 1.0f;
  if (variant == kFullNoDepthCue) options.floor_brightness = 1.0;
  if (variant == kFullAllPoints) options.max_points_per_pixel = 0.0;
  if (variant == kFullHalfPointPerPixel) options.max_points_per_pixel = 0.5;
  OffscreenContext context(kWidth, kHeight);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  renderer.Sync(scene);
  for (auto _ : state) {
    if (variant == kEmptyFrame) {
      renderer.DrawProgress(MapScene(), kWidth, kHeight);
    } else if (variant == kFollowOnly) {
      renderer.BeginFrame(kWidth, kHeight);
      renderer.DrawMap(scene, FollowCamera(scene, kWidth, kHeight, options),
                       Viewport{0, 0, kWidth, kHeight});
    } else {
      renderer.DrawProgress(scene, kWidth, kHeight);
    }
    benchmark::DoNotOptimize(renderer.ReadImage(kWidth, kHeight));
  }
  state.counters["points"] = static_cast<double>(scene.num_points());
  state.counters["drawn"] = static_cast<double>(renderer.num_points_drawn());
  state.SetLabel(context.GlRenderer());
}
BENCHMARK(BM_Render)
    ->ArgsProduct({{1, 5, 10}, {kFull}})
    ->ArgsProduct({{5},
                   {kFullPointSize1, kFullNoDepthCue, kFollowOnly, kFullAllPoints,
                    kFullHalfPointPerPixel, kEmptyFrame}})
    ->ArgNames({"Mpoints", "variant"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);

void BM_Upload(benchmark::State& state) {
  const MapScene& scene = SceneOf(state.range(0));
  OffscreenContext context(kWidth, kHeight);
  for (auto _ : state) {
    MapRenderer renderer(&OffscreenContext::ProcAddress);
    renderer.Sync(scene);
    benchmark::DoNotOptimize(renderer.ReadImage(16, 16));
  }
}
BENCHMARK(BM_Upload)->Arg(5)->ArgName("Mpoints")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace sightmap::render

BENCHMARK_MAIN();
