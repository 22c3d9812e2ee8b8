// Generation speed of the synthetic building at 640x480 (frames/s as items_per_second):
// BM_RenderFrame is the whole frame (render, depth and colour sensor models), the others split it.
// Target: >= 20 frames/s on a 2-core machine.
#include <benchmark/benchmark.h>

#include "sim/simulator.h"

namespace {

using sightmap::sim::Simulator;
using sightmap::sim::SimulatorOptions;
using sightmap::sim::TrajectoryKind;

SimulatorOptions Options(int64_t kind) {
  SimulatorOptions options;
  options.trajectory = kind == 0 ? TrajectoryKind::kHandheld : TrajectoryKind::kRobot;
  return options;
}

void BM_RenderFrame(benchmark::State& state) {
  Simulator simulator(Options(state.range(0)));
  int64_t index = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(simulator.RenderFrame(index));
    index = (index + 7) % simulator.num_frames();
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(state.range(0) == 0 ? "handheld" : "robot");
}
BENCHMARK(BM_RenderFrame)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3.0)
    ->UseRealTime();

void BM_RenderOnly(benchmark::State& state) {
  Simulator simulator(Options(0));
  int64_t index = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        simulator.renderer().Render(simulator.options().camera, simulator.WorldFromCam(index)));
    index = (index + 7) % simulator.num_frames();
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RenderOnly)->Unit(benchmark::kMillisecond)->MinTime(2.0)->UseRealTime();

// The sensor models on one rendered hand-held view.
sightmap::render::RenderedView SampleView(Simulator* simulator) {
  return simulator->renderer().Render(simulator->options().camera, simulator->WorldFromCam(40));
}

void BM_SimulateDepth(benchmark::State& state) {
  Simulator simulator(Options(0));
  const sightmap::render::RenderedView view = SampleView(&simulator);
  uint64_t seed = 1;
  for (auto _ : state) {
    benchmark::DoNotOptimize(sightmap::sim::SimulateDepth(
        view.depth, view.no_depth, simulator.options().camera, simulator.options().depth, seed++));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SimulateDepth)->Unit(benchmark::kMillisecond)->MinTime(2.0)->UseRealTime();

void BM_SimulateColor(benchmark::State& state) {
  Simulator simulator(Options(0));
  const sightmap::render::RenderedView view = SampleView(&simulator);
  uint64_t seed = 1;
  for (auto _ : state) {
    benchmark::DoNotOptimize(sightmap::sim::SimulateColor(view.color, 1.0, Eigen::Vector2d(3, 1),
                                                          simulator.options().color, seed++));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SimulateColor)->Unit(benchmark::kMillisecond)->MinTime(2.0)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
