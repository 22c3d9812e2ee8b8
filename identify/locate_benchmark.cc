// The locate figures of issue 9, run by hand (build/identify/locate_benchmark), not by ctest:
// - per-stage median and p95 over N session-2 phone photos (1280x960) located against a
//   ground-truth-pose model of the office walk (session 1, 1 Hz), the model loaded once as
//   `serve` does; matched share, pose errors, and the visibility against the ground truth;
// - retrieval time on that model and on one 5x larger (--large-factor): the larger model holds
//   the same keyframes' features replicated (each copy moved 100 m along x, as if another floor
//   of the same building), because rendering thousands of keyframes takes minutes. Replicas are the
//   worst case for an inverted index: every posting list grows by the full factor.
//
// What this benchmark measured for LocatorOptions' defaults (100 session-2 photos unless said):
// - features, retrieval_candidates, max_places: 3000 features, 20 candidates and 6 places matched
//   39 of 100 photos, against 35 with 1500, 10 and 4; 5000, 40 and 12 matched 40, and 40
//   candidates with 12 places matched the same 39 at about twice the matching time.
// - reserve_candidates: 40 in reserve with 12 places matched 128 of 200 photos with 3 poses
//   beyond 0.3 m, as 20 candidates and 6 places did (2026-11-30); 60 candidates grouped alike 126
//   with 4 (the SLAM models' figures are in locator.h).
// - match_node_level: level 2 (about 100 nodes) cut matching to 1/30 (p95 of the whole locate
//   404 -> 184 ms), but verified poses went wrong by 0.7 m (1 of 100 photos) and 2.6 m (1 of 17
//   in locator_test), where exhaustive matching has none.
// - min_inlier_share: right poses held 0.021-0.09 of the place's projected points, wrong ones
//   from 0.009.

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/peak_memory.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "identify/identify_eval.h"
#include "identify/locator.h"
#include "identify/sim_model_testing.h"
#include "identify/visibility.h"
#include "sim/simulator.h"
#include "store/model.h"

namespace sightmap::identify {
namespace {

namespace fs = std::filesystem;

// A model holding `factor` copies of `source`'s keyframe features (no images), the copy c moved
// by 100 c metres along x, and its vocabulary and labels.
void ReplicateModel(const store::Model& source, const std::string& path, int factor) {
  store::ModelOptions options;
  options.sync_every_commit = false;
  store::Model model = store::Model::Open(path, options);
  store::SessionRecord session;
  session.source = "replicated";
  const SessionId id = model.BeginSession(session);
  const std::vector<store::KeyframeInfo> infos = source.Keyframes();
  std::vector<Features> features;
  for (const store::KeyframeInfo& info : infos) features.push_back(source.LoadFeatures(info.id));
  for (int copy = 0; copy < factor; ++copy) {
    for (size_t i = 0; i < infos.size(); ++i) {
      store::KeyframeRecord keyframe;
      keyframe.session = id;
      keyframe.timestamp_ns = infos[i].timestamp_ns + copy * int64_t{1000000000000};
      keyframe.world_from_cam = infos[i].world_from_cam;
      keyframe.world_from_cam.translation().x() += 100.0 * copy;
      keyframe.odom_world_from_cam = keyframe.world_from_cam;
      keyframe.intrinsics = infos[i].intrinsics;
      keyframe.features = features[i];
      // The store wants images; tiny blank ones keep the file small (no depth: no occlusion cloud,
      // which retrieval does not use).
      keyframe.color = cv::Mat(12, 16, CV_8UC3, cv::Scalar::all(0));
      keyframe.depth = cv::Mat(12, 16, CV_16UC1, cv::Scalar::all(0));
      model.AddKeyframe(keyframe);
    }
  }
  const auto vocabulary = source.LoadVocabulary();
  model.SetVocabulary(vocabulary->first, vocabulary->second);
  for (const store::LabelRecord& label : source.Labels()) {
    store::LabelRecord copy = label;
    copy.id = LabelId();
    model.AddLabel(copy);
  }
  model.EndSession(id, store::SessionEnd::kFinished, 0);
}

// The share of a photo's view the walk saw from a similar viewpoint: the model's surfaces drawn
// from the photo's true pose (the occlusion cloud, 1/16 resolution); a pixel counts as covered
// when some keyframe saw its surface point (in its image, its depth within 10 cm) from a ray
// within `max_angle_deg` of the photo's and a distance within a factor `max_scale` (ORB's pyramid
// spans 3.6x). Local features can only match what is covered: this bounds the matched share.
class ViewCoverage {
 public:
  ViewCoverage(const store::Model& model, double max_angle_deg, double max_scale)
      : cos_max_(std::cos(DegToRad(max_angle_deg))), max_scale_(max_scale) {
    OcclusionCloudBuilder builder(0.05);
    for (const store::KeyframeInfo& info : model.Keyframes()) {
      const cv::Mat depth = model.LoadDepth(info.id);
      if (depth.empty()) continue;
      builder.AddDepth(depth, info.intrinsics, info.world_from_cam, 4, 0.3, 5.0);
      views_.push_back({MakeSightingView(depth, info.intrinsics, info.world_from_cam, 160, 120),
                        info.world_from_cam.translation()});
    }
    cloud_ = builder.Build();
  }

  double Of(const sim::QueryPhoto& photo) const {
    const Intrinsics small =
        photo.intrinsics.Scaled(photo.intrinsics.width / 16, photo.intrinsics.height / 16);
    VisibilityOptions options;
    options.max_splat_radius_px = 2;
    const cv::Mat surface = RenderOcclusionDepth(cloud_, small, photo.world_from_cam, options);
    const Eigen::Vector3d centre = photo.world_from_cam.translation();
    std::vector<const View*> near;
    for (const View& view : views_) {
      if ((view.centre - centre).norm() < 8.0) near.push_back(&view);
    }
    int covered = 0;
    for (int v = 0; v < surface.rows; ++v) {
      for (int u = 0; u < surface.cols; ++u) {
        const float z = surface.at<float>(v, u);
        if (!std::isfinite(z)) continue;
        const Eigen::Vector3d world = photo.world_from_cam * small.Unproject(u, v, z);
        const Eigen::Vector3d photo_ray = world - centre;
        for (const View* view : near) {
          const Eigen::Vector3d ray = world - view->centre;
          const double scale = ray.norm() / photo_ray.norm();
          if (scale > max_scale_ || scale < 1.0 / max_scale_) continue;
          if (ray.dot(photo_ray) < cos_max_ * ray.norm() * photo_ray.norm()) continue;
          const SightingView& seen = view->sighting;
          const Eigen::Vector3d cam = seen.cam_from_world * world;
          if (cam.z() <= 0.1) continue;
          const Eigen::Vector2d px = seen.intrinsics.Project(cam);
          const int pu = static_cast<int>(std::lround(px.x()));
          const int pv = static_cast<int>(std::lround(px.y()));
          if (pu < 0 || pv < 0 || pu >= seen.depth_mm.cols || pv >= seen.depth_mm.rows) continue;
          const double seen_m = seen.depth_mm.at<uint16_t>(pv, pu) * 1e-3;
          if (std::abs(seen_m - cam.z()) > 0.1) continue;
          ++covered;
          break;
        }
      }
    }
    return static_cast<double>(covered) / (surface.rows * surface.cols);
  }

 private:
  struct View {
    SightingView sighting;   // its depth at 160x120
    Eigen::Vector3d centre;  // the keyframe's camera in the world [m]
  };
  double cos_max_;
  double max_scale_;
  OcclusionCloud cloud_;
  std::vector<View> views_;
};

struct BenchmarkArgs {
  int keyframes = 600;
  int photos = 100;
  int large_factor = 5;
  std::string dir = (fs::temp_directory_path() / "sightmap-locate-benchmark").string();
  bool keep = false;
  int vocabulary_keyframes = 30;
  LocatorOptions locator_options;
  bool coverage = false;
  bool estimate = false;
};

void Declare(CLI::App& app, BenchmarkArgs* args) {
  app.add_option("--keyframes", args->keyframes, "1 Hz keyframes of the walk in the model");
  app.add_option("--photos", args->photos, "session-2 phone photos located");
  app.add_option("--large-factor", args->large_factor, "the larger model's size / the model's");
  app.add_option("--dir", args->dir, "folder for the models (reused when they exist)");
  app.add_flag("--keep", args->keep, "keep the models for the next run");
  app.add_option("--vocabulary-keyframes", args->vocabulary_keyframes,
                 "keyframes the vocabulary is trained from (0 = all; the mapper uses 30)");
  LocatorOptions& options = args->locator_options;
  app.add_option("--max-side", options.max_image_side_px, "photo side for features [px]");
  app.add_option("--photo-features", options.features.max_features, "features per photo");
  app.add_option("--candidates", options.retrieval_candidates, "retrieval candidates");
  app.add_option("--reserve", options.reserve_candidates,
                 "retrieval candidates after those that only make places of their own");
  app.add_option("--neighbours", options.max_neighbours, "neighbours per candidate");
  app.add_option("--neighbour-radius", options.neighbour_radius_m, "[m]");
  app.add_option("--node-level", options.match_node_level,
                 "vocabulary level whose nodes bound matching (0 = exhaustive)");
  app.add_option("--ratio", options.match_ratio, "descriptor ratio test");
  app.add_option("--reprojection", options.pnp_reprojection_px, "PnP threshold [px]");
  app.add_option("--min-inliers", options.min_inliers, "inliers to count as matched");
  app.add_option("--confident-inliers", options.confident_inliers, "inliers that end the search");
  app.add_option("--places", options.max_places, "places verified per photo");
  // Read as `--config` reads it, so the names are the locator's own.
  app.add_option_function<std::string>(
      "--second-look-retrieval",
      [&options](std::string name) {
        std::transform(name.begin(), name.end(), name.begin(),
                       [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
        try {
          options_json::ParseInto(nlohmann::json{{"second_look_retrieval", name}}.dump(),
                                  "--second-look-retrieval", options);
        } catch (const Error& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      "keyframes RootSIFT's second look tries first: vlad or orb");
  app.add_option("--min-cells", options.min_inlier_cells, "grid cells inliers cover");
  app.add_option("--runner-up-ratio", options.min_inlier_ratio_over_runner_up,
                 "inliers over a disagreeing runner-up's");
  app.add_option("--min-share", options.min_inlier_share, "inliers / projected points");
  app.add_option("--min-view-agreement", options.min_view_agreement,
                 "view check's least agreement (0 = off)");
  app.add_option("--guided-rounds", options.guided_rounds, "guided matching rounds");
  app.add_option("--occlusion-margin", options.occlusion_margin_m,
                 "occlusion margin at the camera [m]");
  app.add_option("--occlusion-margin-ratio", options.occlusion_margin_ratio,
                 "occlusion margin per metre of depth");
  app.add_flag("--coverage", args->coverage,
               "measure, by ground truth, how much of each photo's view the walk saw");
  app.add_flag("--estimate-intrinsics", args->estimate, "locate without the photos' intrinsics");
}

// The ground-truth model of the walk in args.dir, built when it is not there yet.
std::string OpenOrBuildModel(const BenchmarkArgs& args) {
  fs::create_directories(args.dir);
  const std::string model_path =
      (fs::path(args.dir) / ("walk-" + std::to_string(args.keyframes) + "-v" +
                             std::to_string(args.vocabulary_keyframes) + ".db"));
  if (!fs::exists(model_path)) {
    SimModelOptions options;
    options.keyframes = args.keyframes;
    options.vocabulary_keyframes = args.vocabulary_keyframes;
    std::printf("building a %d-keyframe ground-truth model of the office walk...\n",
                args.keyframes);
    std::fflush(stdout);
    const SimModelSummary summary = BuildSimulatorModel(model_path, options);
    std::printf("  %d keyframes, %d labels in %.1f s\n", summary.keyframes, summary.labels,
                summary.seconds);
  }
  return model_path;
}

// Each photo located, as `sightmap eval identify` scores the answers, with the pose errors, the
// photos of places the walk saw and (with a ViewCoverage) matches per band of the view seen.
struct LocateFigures {
  std::vector<QueryTruth> truths;
  std::vector<PhotoAnswer> answers;
  std::vector<double> position_mm;
  std::vector<double> rotation_deg;
  int wrong = 0;  // matched more than 0.3 m from the truth
  int seen_photos = 0;
  int seen_matched = 0;
  // Per coverage band [0, 10%), [10, 25%), [25, 50%), [50, 100%]: photos and matched photos.
  static constexpr double kBandEdges[] = {0.0, 0.10, 0.25, 0.50, 1.01};
  int band_photos[4] = {0, 0, 0, 0};
  int band_matched[4] = {0, 0, 0, 0};
};

LocateFigures LocatePhotos(const Locator& locator, const store::Model& model,
                           const sim::Simulator& simulator,
                           const std::vector<sim::QueryPhoto>& queries, const BenchmarkArgs& args) {
  LocateFigures figures;
  std::vector<Eigen::Isometry3d> keyframes_world_from_cam;
  for (const store::KeyframeInfo& info : model.Keyframes()) {
    keyframes_world_from_cam.push_back(info.world_from_cam);
  }
  std::optional<ViewCoverage> view_coverage;
  if (args.coverage) view_coverage.emplace(model, 40.0, 2.0);
  for (const sim::QueryPhoto& photo : queries) {
    const LocateResult result =
        locator.Locate(photo.image, args.estimate ? std::nullopt : std::optional(photo.intrinsics));
    if (view_coverage) {
      const double share = view_coverage->Of(photo);
      for (int b = 0; b < 4; ++b) {
        if (share >= LocateFigures::kBandEdges[b] && share < LocateFigures::kBandEdges[b + 1]) {
          ++figures.band_photos[b];
          figures.band_matched[b] += result.matched;
        }
      }
      std::printf("  photo %3d: %2.0f%% of its view seen by the walk from within 40 deg, 2x\n",
                  photo.index, 100.0 * share);
    }
    QueryTruth truth;
    for (const sim::ApplianceVisibility& visibility : photo.visibility) {
      truth.appliances
          [simulator.scene().appliances[static_cast<size_t>(visibility.appliance_id - 1)].name] =
          ParseTruthType(sim::ToString(visibility.type));
    }
    figures.truths.push_back(std::move(truth));
    figures.answers.push_back(ToPhotoAnswer(result));
    const bool seen = WalkSawPlace(keyframes_world_from_cam, photo.world_from_cam);
    figures.seen_photos += seen;
    if (seen && result.matched) ++figures.seen_matched;
    if (!result.matched) {
      std::printf("  photo %3d not matched%s: %s\n", photo.index, seen ? " (seen)" : "",
                  result.reason.c_str());
      continue;
    }
    const double error_m =
        (result.world_from_cam.translation() - photo.world_from_cam.translation()).norm();
    figures.wrong += error_m > 0.3;
    std::printf(
        "  photo %3d %s by %.2f m%s: %d inliers of %d matches, runner-up %d, %d projected, %d "
        "cells\n",
        photo.index, error_m > 0.3 ? "WRONG" : "right", error_m, seen ? " (seen)" : "",
        result.inliers, result.matches, result.runner_up_inliers, result.projected_points,
        result.inlier_cells);
    figures.position_mm.push_back(1e3 * error_m);
    figures.rotation_deg.push_back(
        RotationAngleDeg(result.world_from_cam.linear(), photo.world_from_cam.linear()));
  }
  return figures;
}

void PrintFigures(const LocateFigures& figures, size_t num_photos, size_t num_keyframes,
                  bool coverage) {
  const IdentifyEvaluation evaluation = EvaluateIdentification(figures.truths, figures.answers);
  std::fflush(stdout);
  std::printf("\nlocate, %zu photos of 1280x960 against %zu keyframes (one thread):\n", num_photos,
              num_keyframes);
  for (const char* stage : {"features", "retrieval", "matching", "pnp", "visibility", "total"}) {
    const StageTiming& s = evaluation.stages.at(stage);
    std::printf("  %-11s median %7.1f ms  p95 %7.1f ms  mean %7.1f ms\n", stage, s.median_ms,
                s.p95_ms, s.mean_ms);
  }
  const std::vector<double>& position_mm = figures.position_mm;
  const std::vector<double>& rotation_deg = figures.rotation_deg;
  std::printf(
      "matched %d of %zu (%.1f%%); position error median %.1f mm p95 %.1f mm max %.1f mm; "
      "rotation median %.2f deg p95 %.2f deg max %.2f deg\n",
      evaluation.matched_photos, num_photos, 100.0 * evaluation.matched_ratio,
      Percentile(position_mm, 0.5), Percentile(position_mm, 0.95), Percentile(position_mm, 1.0),
      Percentile(rotation_deg, 0.5), Percentile(rotation_deg, 0.95), Percentile(rotation_deg, 1.0));
  std::printf("wrong poses (> 0.3 m): %d\n", figures.wrong);
  std::printf(
      "photos of places the walk saw (a keyframe within 1.5 m and 40 deg): %d, matched "
      "%d\n",
      figures.seen_photos, figures.seen_matched);
  std::printf(
      "recall >= 0.8: %d of %d photos (%.1f%%); precision >= 0.8: %d of %d (%.1f%%); "
      "occluded reported visible: %d of %d (%.1f%%)\n",
      evaluation.recall_good_photos, evaluation.recall_defined_photos,
      100.0 * evaluation.recall_ge_0_8_ratio, evaluation.precision_good_photos,
      evaluation.precision_defined_photos, 100.0 * evaluation.precision_ge_0_8_ratio,
      evaluation.occluded_identified, evaluation.occluded_instances,
      100.0 * evaluation.occluded_false_positive_ratio);
  if (!coverage) return;
  std::printf(
      "\nshare of the photo's view some keyframe saw from within 40 deg and a distance factor "
      "of 2:\n");
  for (int b = 0; b < 4; ++b) {
    std::printf("  %3.0f-%3.0f%%: %3d photos, %3d matched\n", 100.0 * LocateFigures::kBandEdges[b],
                std::min(100.0, 100.0 * LocateFigures::kBandEdges[b + 1]), figures.band_photos[b],
                figures.band_matched[b]);
  }
}

// Retrieval from the model and from one `large_factor` times its size, interleaved so both see
// the same machine load.
void MeasureRetrievalScaling(const store::Model& model, const Locator& locator,
                             const std::vector<sim::QueryPhoto>& queries,
                             const BenchmarkArgs& args) {
  const std::string large_path =
      (fs::path(args.dir) / ("walk-" + std::to_string(args.keyframes) + "-x" +
                             std::to_string(args.large_factor) + ".db"));
  if (!fs::exists(large_path)) {
    const auto start = std::chrono::steady_clock::now();
    ReplicateModel(model, large_path, args.large_factor);
    std::printf("\nreplicated model written in %.1f s\n", SecondsSince(start));
    std::fflush(stdout);
  }
  store::ModelOptions read_only;
  read_only.read_only = true;
  const store::Model large_model = store::Model::Open(large_path, read_only);
  const Locator large(large_model, args.locator_options);
  std::vector<double> small_retrieval, large_retrieval;
  for (const sim::QueryPhoto& photo : queries) {
    small_retrieval.push_back(locator.Locate(photo.image, photo.intrinsics).timings.retrieval_ms);
    large_retrieval.push_back(large.Locate(photo.image, photo.intrinsics).timings.retrieval_ms);
  }
  const auto mean = [](const std::vector<double>& ms) {
    return std::accumulate(ms.begin(), ms.end(), 0.0) / static_cast<double>(ms.size());
  };
  std::printf(
      "\nretrieval (%s; second look: %s), %zu photos:\n",
      args.locator_options.retrieval == LocatorOptions::Retrieval::kVotes
          ? "bag-of-words shortlist re-ranked by votes"
          : "bag of words + inverted index",
      args.locator_options.second_look_retrieval == LocatorOptions::SecondLookRetrieval::kVlad
          ? "VLAD first"
          : "ORB's candidates",
      queries.size());
  for (const auto& [keyframe_count, ms] : {std::pair(locator.NumKeyframes(), small_retrieval),
                                           std::pair(large.NumKeyframes(), large_retrieval)}) {
    std::printf("  %5zu keyframes: median %.2f ms  p95 %.2f ms  mean %.2f ms\n", keyframe_count,
                Percentile(ms, 0.5), Percentile(ms, 0.95), mean(ms));
  }
  std::printf("  ratio of medians %.2f, of means %.2f\n",
              Percentile(large_retrieval, 0.5) / Percentile(small_retrieval, 0.5),
              mean(large_retrieval) / mean(small_retrieval));
  if (!args.keep) fs::remove(large_path);
}

int Run(int argc, char** argv) {
  CLI::App app("Locate timings per stage and retrieval scaling (issue 9)", "locate_benchmark");
  BenchmarkArgs args;
  Declare(app, &args);
  CLI11_PARSE(app, argc, argv);

  const std::string model_path = OpenOrBuildModel(args);
  const store::Model model = store::Model::Open(model_path);  // writable: upgrades a kept model
  auto start = std::chrono::steady_clock::now();
  const Locator locator(model, args.locator_options);
  std::printf("locator loaded: %zu keyframes, %zu occlusion voxels in %.1f s\n",
              locator.NumKeyframes(), locator.NumOcclusionVoxels(), SecondsSince(start));
  sim::Simulator simulator(PhotoSessionOptions());
  start = std::chrono::steady_clock::now();
  const std::vector<sim::QueryPhoto> queries =
      simulator.MakeQueries(args.photos, sim::QueryOptions());
  std::printf("%d session-2 photos rendered in %.1f s\n", args.photos, SecondsSince(start));

  const LocateFigures figures = LocatePhotos(locator, model, simulator, queries, args);
  PrintFigures(figures, queries.size(), locator.NumKeyframes(), args.coverage);
  if (args.large_factor > 1) MeasureRetrievalScaling(model, locator, queries, args);
  std::printf("peak RSS %.0f MiB\n", PeakRssMiB());
  if (!args.keep) fs::remove(model_path);
  return 0;
}

}  // namespace
}  // namespace sightmap::identify

int main(int argc, char** argv) { return sightmap::identify::Run(argc, argv); }
