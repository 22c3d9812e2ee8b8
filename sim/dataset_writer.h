// Writes a simulated walk and phone photos to disk (`sightmap sim generate`):
//   DIR/rgb/T.png, DIR/depth/T.png      colour (8-bit BGR) and depth (16-bit, 5000 per metre)
//   DIR/rgb.txt, DIR/depth.txt          TUM lists "timestamp filename" (seconds)
//   DIR/groundtruth.txt                 TUM poses "timestamp tx ty tz qx qy qz qw" (world_from_cam)
//   DIR/calibration.json                the RGB-D intrinsics (capture/calibration.h format)
//   DIR/appliances.json                 {"scene", "appliances": [{"id", "name", "type",
//                                         "points": [[x, y, z], ...]}]}
//   DIR/queries/NNNN.jpg, queries.json  phone photos with intrinsics, ground-truth pose
//                                        (world_from_cam: "position" [m], "quaternion_xyzw") and
//                                        per-appliance "types" (not_visible / occluded /
//                                        partially_visible / visible) with the pixel counts
//   DIR/overview.png                    floor plan with the trajectory, photos and appliances
// The folder plays back as `tum:DIR`.
#pragma once

#include <ostream>
#include <string>

#include "sim/simulator.h"

namespace sightmap::sim {

struct GenerateOptions {
  SimulatorOptions simulator;
  int queries = 20;  // phone photos to write
  QueryOptions query;
  std::string out_dir;

  bool Check(std::string* error) const;
};

struct GenerateSummary {
  int64_t frames = 0;
  int queries = 0;
  double seconds = 0.0;          // wall-clock time [s]
  double frames_per_second = 0;  // frames rendered and written per wall-clock second
};

// Progress lines go to `progress` (may be nullptr) every few seconds.
GenerateSummary GenerateDataset(const GenerateOptions& options, std::ostream* progress);

}  // namespace sightmap::sim
