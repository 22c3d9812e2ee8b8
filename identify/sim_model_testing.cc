#include "identify/sim_model_testing.h"

#include <chrono>
#include <cmath>
#include <filesystem>

#include "core/check.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "store/model.h"

namespace sightmap::identify {

bool SimModelOptions::Check(std::string* error) const {
  const char* why = nullptr;
  if (keyframes < 2)
    why = "keyframes must be at least 2 (the vocabulary needs two images)";
  else if (!(fps > 0.0))
    why = "fps must be positive";
  else if (vocabulary_keyframes < 0)
    why = "vocabulary_keyframes must not be negative";
  else if (!features.Check(error) || !vocabulary.Check(error) ||
           (store_photo_features && !photo_features.Check(error)))
    return false;
  if (why == nullptr) return true;
  if (error != nullptr) *error = std::string("SimModelOptions: ") + why;
  return false;
}

SimModelSummary BuildSimulatorModel(const std::string& path, const SimModelOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!std::filesystem::exists(path),
                 "BuildSimulatorModel writes a new model, and " << path << " exists");
  const auto start = std::chrono::steady_clock::now();
  sim::SimulatorOptions sim_options;
  sim_options.scene = options.scene;
  sim_options.trajectory = options.trajectory;
  sim_options.session = options.session;
  sim_options.seed = options.seed;
  sim_options.fps = options.fps;
  sim_options.frames = options.keyframes;
  sim::Simulator simulator(sim_options);
  const Intrinsics camera = simulator.options().camera;

  store::ModelOptions model_options;
  model_options.sync_every_commit = false;  // a throwaway model: speed over power-cut safety
  store::Model model = store::Model::Open(path, model_options);
  store::SessionRecord session;
  session.source = "sim:" + options.scene + " (ground-truth poses)";
  session.intrinsics = camera;
  const SessionId session_id = model.BeginSession(session);

  SimModelSummary summary;
  std::vector<cv::Mat> training;
  const int frames = static_cast<int>(std::min<int64_t>(options.keyframes, simulator.num_frames()));
  for (int i = 0; i < frames; ++i) {
    const RgbdFrame frame = simulator.RenderFrame(i);
    const Eigen::Isometry3d world_from_cam = simulator.WorldFromCam(i);
    const Features features =
        slam::ExtractFeatures(frame.color, frame.depth, camera, options.features);
    store::KeyframeRecord keyframe;
    keyframe.session = session_id;
    keyframe.timestamp_ns = frame.timestamp_ns;
    keyframe.world_from_cam = world_from_cam;
    keyframe.odom_world_from_cam = world_from_cam;
    keyframe.intrinsics = camera;
    keyframe.color = frame.color;
    keyframe.depth = frame.depth;  // the Locator's occlusion cloud
    keyframe.features = features;
    const KeyframeId id = model.AddKeyframe(keyframe);
    if (options.store_photo_features) {
      model.SetPhotoFeatures(id, mapping::ExtractPhotoFeatures(frame.color, frame.depth, camera,
                                                               options.photo_features));
    }
    if ((options.vocabulary_keyframes == 0 || i < options.vocabulary_keyframes) &&
        features.descriptors.rows > 0) {
      training.push_back(features.descriptors);
    }
    summary.world_from_cam.push_back(world_from_cam);
  }
  if (options.write_vocabulary) {
    model.SetVocabulary(slam::Vocabulary::kFormat,
                        slam::Vocabulary::Train(training, options.vocabulary).Serialize());
  }
  if (options.label_appliances) {
    for (const sim::Appliance& appliance : simulator.scene().appliances) {
      store::LabelRecord label;
      label.name = appliance.name;
      label.type = appliance.type;
      for (const Eigen::Vector3d& point : appliance.points) {
        store::LabelPoint labelled;
        labelled.world = point;
        labelled.source = store::LabelPointSource::kTyped;
        label.points.push_back(labelled);
      }
      model.AddLabel(label);
      ++summary.labels;
    }
  }
  model.EndSession(session_id, store::SessionEnd::kFinished, 0);
  summary.keyframes = frames;
  summary.seconds = SecondsSince(start);
  return summary;
}

sim::SimulatorOptions PhotoSessionOptions() {
  sim::SimulatorOptions options;
  options.session = 2;
  options.seed = 7;
  options.fps = 1.0;
  options.frames = 1;
  return options;
}

bool WalkSawPlace(const std::vector<Eigen::Isometry3d>& keyframes_world_from_cam,
                  const Eigen::Isometry3d& photo_world_from_cam, double max_distance_m,
                  double max_angle_deg) {
  const double min_cos = std::cos(DegToRad(max_angle_deg));
  for (const Eigen::Isometry3d& keyframe : keyframes_world_from_cam) {
    if ((keyframe.translation() - photo_world_from_cam.translation()).norm() < max_distance_m &&
        keyframe.linear().col(2).dot(photo_world_from_cam.linear().col(2)) > min_cos) {
      return true;
    }
  }
  return false;
}

}  // namespace sightmap::identify
