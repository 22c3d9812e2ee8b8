// The synthetic building as an RgbdSource: `sim:NAME[?key=value&...]` streams the simulated walk
// straight into any consumer, without files.
//
//   NAME        office (the embedded scene) or a scene JSON file
//   trajectory  handheld (default) | robot | survey (sim/survey.h)
//   session     >= 1 (default 1)
//   seed        unsigned integer (default 1)
//   fps         frame rate [Hz] (default 30; 1 renders only the frames a 1 Hz capture keeps)
//   frames      frames to deliver (default: 300 s of walk at `fps`; a survey: one lap)
// e.g. sim:office?trajectory=robot&session=2&seed=3&frames=100&fps=1
// Frames carry world_from_cam_gt; metadata().has_ground_truth is true.
#pragma once

#include <memory>
#include <string>

#include "capture/rgbd_source.h"
#include "sim/simulator.h"

namespace sightmap::sim {

// Parses "NAME?key=value&..." (the part after "sim:"). Throws InvalidArgument naming a bad key.
SimulatorOptions ParseSimLocation(const std::string& location);

std::unique_ptr<capture::RgbdSource> OpenSimSource(const SimulatorOptions& options);

// Makes OpenSource("sim:...") open the simulator. Call once at start-up (cli main does).
void RegisterSimSource();

}  // namespace sightmap::sim
