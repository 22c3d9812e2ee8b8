// A model built from the simulator's walk with its GROUND-TRUTH poses (no SLAM in the loop), every
// appliance labelled from the scene: what the Locator's tests, its benchmark and the
// identification evaluation locate session-2 phone photos against. Test-only (sits on sim/).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mapping/photo_features.h"
#include "sim/simulator.h"
#include "slam/features.h"
#include "slam/vocabulary.h"

namespace sightmap::identify {

struct SimModelOptions {
  // The walk: scene, trajectory, session and seed as in SimulatorOptions; keyframes at fps.
  std::string scene = "office";
  sim::TrajectoryKind trajectory = sim::TrajectoryKind::kHandheld;
  int session = 1;
  uint64_t seed = 7;
  double fps = 1.0;    // [Hz], the mapper's keyframe rate
  int keyframes = 90;  // frames 0 .. keyframes-1 of the walk
  // Keyframe features as the mapper extracts them.
  slam::FeatureOptions features;
  // RootSIFT for photos stored per keyframe, as `sightmap map` stores it; false leaves the
  // Locator to extract it while loading (a model mapped before they were stored).
  bool store_photo_features = true;
  mapping::PhotoFeatureExtraction photo_features;
  // The vocabulary is trained from the first vocabulary_keyframes keyframes' descriptors (the
  // mapper trains from its first 30); 0 = all keyframes.
  int vocabulary_keyframes = 30;
  slam::VocabularyOptions vocabulary;
  // false: the model stores no vocabulary, as a map run of fewer keyframes than the mapper trains
  // on leaves it.
  bool write_vocabulary = true;
  // Every scene appliance as a label (its points in the world frame).
  bool label_appliances = true;

  bool Check(std::string* error) const;
};

struct SimModelSummary {
  int keyframes = 0;
  int labels = 0;
  std::vector<Eigen::Isometry3d> world_from_cam;  // ground truth, per keyframe
  double seconds = 0.0;                           // time to build [s]
};

// Writes a new model at `path` (which must not exist yet).
SimModelSummary BuildSimulatorModel(const std::string& path, const SimModelOptions& options);

// The simulator the phone photos come from: session 2 (other lighting, chairs moved), seed 7, one
// walk frame (only its MakeQueries is wanted).
sim::SimulatorOptions PhotoSessionOptions();

// Whether a photo shows a place the walk saw: a keyframe stands within max_distance_m of the
// photo's camera and looks within max_angle_deg of its direction. Photos of places never seen
// cannot be expected to match.
bool WalkSawPlace(const std::vector<Eigen::Isometry3d>& keyframes_world_from_cam,
                  const Eigen::Isometry3d& photo_world_from_cam, double max_distance_m = 1.5,
                  double max_angle_deg = 40.0);

}  // namespace sightmap::identify
