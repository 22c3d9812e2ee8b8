// Generation speed of the synthetic building at 640x480: render, depth and colour sensor models
// (frames/s as items_per_second). Target: >= 20 frames/s on a 2-core machine.
#include <benchmark/benchmark.h>

#include "sim/simulator.h"

namespace {

void BM_RenderFrame(benchmark::State& state) {
  sightmap::sim::SimulatorOptions options;
  options.trajectory = state.range(0) == 0 ? sightmap::sim::TrajectoryKind::kHandheld
                                           : sightmap::sim::TrajectoryKind::kRobot;
  options.fps = 30.0;
  sightmap::sim::Simulator simulator(options);
  int64_t index = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(simulator.RenderFrame(index));
    index = (index + 7) % simulator.num_frames();
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(options.trajectory == sightmap::sim::TrajectoryKind::kRobot ? "robot"
                                                                             : "handheld");
}
BENCHMARK(BM_RenderFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
