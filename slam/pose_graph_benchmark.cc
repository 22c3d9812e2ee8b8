// Pose-graph timings, run by hand (not a ctest test):
//   build/slam/pose_graph_benchmark [--benchmark_filter=...]
// 2,000 poses (4 laps of 500 around a 4 m circle, odometry 5 mm / 0.1 degree noise) with 20
// correct loops, with and without one false loop (which costs a second solve). The CPU column
// is the one to quote on a shared machine.
#include <benchmark/benchmark.h>

#include "core/rotation.h"
#include "slam/pose_graph.h"
#include "slam/synthetic_pose_graph.h"

namespace sightmap::slam {
namespace {

synthetic::Scene MakeScene(bool with_false_loop) {
  synthetic::Scene scene = synthetic::MakeCircleScene(synthetic::LargeCircleOptions());
  if (with_false_loop) {
    PoseGraphEdge edge;
    edge.from = 100;
    edge.to = 350;
    // Place recognition confuses pose 350 (on the far side of the circle) with a view 30 cm in
    // front of pose 100.
    edge.to_in_from =
        ExpSe3((Eigen::Matrix<double, 6, 1>() << 0.05, 0.0, 0.3, 0.0, 0.09, 0.0).finished());
    const synthetic::CircleOptions options = synthetic::LargeCircleOptions();
    edge.information = synthetic::Information(options.loop_sigma_m, options.loop_sigma_rad);
    edge.type = LinkType::kLoopClosure;
    scene.graph.AddEdge(edge);
  }
  return scene;
}

void BM_Optimize2000Poses(benchmark::State& state) {
  const bool with_false_loop = state.range(0) != 0;
  const synthetic::Scene scene = MakeScene(with_false_loop);
  PoseGraphOptions options;
  options.max_solver_time_s = 60.0;  // measure the whole solve, not the default time bound
  PoseGraphSummary summary;
  double rmse_before = synthetic::PositionRmse(scene.graph, scene.truth);
  double rmse_after = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraph graph = scene.graph;
    state.ResumeTiming();
    summary = graph.Optimize(options);
    state.PauseTiming();
    rmse_after = synthetic::PositionRmse(graph, scene.truth);
    state.ResumeTiming();
  }
  state.counters["solves"] = summary.solves;
  state.counters["iterations"] = summary.iterations;
  state.counters["rejected"] = static_cast<double>(summary.rejected_edges.size());
  state.counters["converged"] = summary.converged ? 1 : 0;
  state.counters["rmse_before_m"] = rmse_before;
  state.counters["rmse_after_m"] = rmse_after;
}
BENCHMARK(BM_Optimize2000Poses)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sightmap::slam

BENCHMARK_MAIN();
