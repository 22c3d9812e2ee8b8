// Frames of a simulated walk for the slam tests (a test-only dependency on sim/, which sits above
// slam/ in the layers).
#pragma once

#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "core/rgbd_frame.h"
#include "sim/simulator.h"

namespace sightmap::testing {

struct SimWalk {
  Intrinsics camera;
  std::vector<RgbdFrame> frames;  // frames[i].index is the walk's frame index
};

// Renders frames [first_frame, options.frames) of the walk `options` describes.
inline SimWalk RenderSimWalk(const sim::SimulatorOptions& options, int64_t first_frame = 0) {
  sim::Simulator simulator(options);
  SimWalk walk;
  walk.camera = simulator.options().camera;
  for (int64_t i = first_frame; i < simulator.num_frames(); ++i) {
    walk.frames.push_back(simulator.RenderFrame(i));
  }
  return walk;
}

// Frames [first, end) of the robot walk, seed 11, at 10 Hz: the stretches the tracker and dense
// alignment tests pick out of it.
inline SimWalk RenderRobotWalk(int64_t first, int64_t end) {
  sim::SimulatorOptions options;
  options.trajectory = sim::TrajectoryKind::kRobot;
  options.fps = 10.0;
  options.frames = end;
  options.seed = 11;
  return RenderSimWalk(options, first);
}

}  // namespace sightmap::testing
