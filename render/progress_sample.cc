// Writes a sample progress image of the synthetic office: the walk's 1 Hz frames with their
// ground-truth poses become keyframes (voxel-downsampled), fed through the ProgressWriter exactly
// as the mapper will feed it. Loop edges join keyframes that revisit a place (by ground truth),
// to show how loops are drawn.
//
//   render_progress_sample [OUTPUT.png [KEYFRAMES [SESSIONS]]]   (default /tmp/progress-sample.png,
//   100, 1)
#include <chrono>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "core/timing.h"
#include "render/progress_writer.h"
#include "sim/simulator.h"

int main(int argc, char** argv) {
  using namespace sightmap;          // NOLINT: a small tool
  using namespace sightmap::render;  // NOLINT
  const std::string output = argc > 1 ? argv[1] : "/tmp/progress-sample.png";
  const int keyframes = argc > 2 ? std::atoi(argv[2]) : 100;
  const int sessions = argc > 3 ? std::atoi(argv[3]) : 1;
  try {
    ProgressWriterOptions options;
    options.png_path = output;
    options.every_n_keyframes = 10;
    ProgressWriter writer(options);
    const auto start = std::chrono::steady_clock::now();
    std::vector<Eigen::Isometry3d> poses;
    int64_t loops = 0;
    for (int session = 1; session <= sessions; ++session) {
      sim::SimulatorOptions sim_options;
      sim_options.fps = 1.0;
      sim_options.session = session;
      sim_options.frames = keyframes;
      sim::Simulator simulator(sim_options);
      if (session == 1) {
        MapUpdate labels;
        labels.appliances.emplace();
        for (const sim::Appliance& appliance : simulator.scene().appliances) {
          if (!appliance.points.empty()) {
            labels.appliances->push_back({appliance.name, appliance.points.front()});
          }
        }
        writer.Submit(std::move(labels));
      }
      for (int64_t i = 0; i < simulator.num_frames(); ++i) {
        const RgbdFrame frame = simulator.RenderFrame(i);
        MapUpdate update;
        MapKeyframe keyframe = FromRgbd(frame.color, frame.depth, sim_options.camera);
        keyframe.id = static_cast<int64_t>(poses.size());
        keyframe.session = session;
        keyframe.world_from_cam = simulator.WorldFromCam(i);
        // A loop edge to the earliest keyframe at the same place, at least 30 keyframes back.
        for (size_t j = 0; j + 30 < poses.size(); ++j) {
          if ((poses[j].translation() - keyframe.world_from_cam.translation()).norm() < 0.4) {
            update.loops.push_back({static_cast<int64_t>(j), keyframe.id});
            ++loops;
            break;
          }
        }
        poses.push_back(keyframe.world_from_cam);
        update.camera = keyframe.world_from_cam;
        update.keyframes.push_back(std::move(keyframe));
        const double elapsed = SecondsSince(start);
        update.status = MapStatus{static_cast<int64_t>(poses.size()), loops,
                                  TrackingState::kTracking, poses.size() / elapsed, elapsed};
        writer.Submit(std::move(update));
      }
    }
    writer.Finish();
    const ProgressWriterStats stats = writer.stats();
    std::cout << "wrote " << output << ": " << stats.keyframes << " keyframes, " << stats.renders
              << " renders (" << stats.renders_skipped << " skipped), last render "
              << stats.last_render_ms << " ms on " << stats.gl_renderer << "\n";
    if (!stats.last_error.empty()) std::cerr << "error: " << stats.last_error << "\n";
    return stats.pngs_written > 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
