// sightmap info MODEL [--json]: what a model holds. Scripts read the --json keys; they are stable.
#include <iomanip>
#include <iostream>
#include <optional>

#include <nlohmann/json.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "identify/coverage.h"
#include "mapping/photo_features.h"
#include "store/model.h"

namespace sightmap::cli {

namespace {

// Each session with the options it ran with (what `map --config` reads; older models stored
// fewer of them).
nlohmann::json SessionsJson(const std::vector<store::SessionRecord>& sessions) {
  nlohmann::json list = nlohmann::json::array();
  for (const store::SessionRecord& session : sessions) {
    nlohmann::json options = nlohmann::json::parse(session.options_json, nullptr,
                                                   /*allow_exceptions=*/false);
    if (options.is_discarded()) options = nullptr;
    list.push_back({{"id", session.id.value()},
                    {"source", session.source},
                    {"device", session.device_name},
                    {"end", store::SessionEndName(session.end_state)},
                    {"start_time_ns", session.start_time_ns},
                    {"end_time_ns", session.end_time_ns},
                    {"options", options}});
  }
  return list;
}

nlohmann::json InfoJson(const store::Model& model, const store::ModelSummary& summary,
                        const std::vector<store::LabelRecord>& labels,
                        const std::optional<identify::ModelCoverage>& coverage) {
  nlohmann::json out;
  out["schema_version"] = summary.schema_version;
  out["sessions"] = summary.sessions;
  out["keyframes"] = summary.keyframes;
  out["loop_closures"] = summary.loop_closures;
  out["segments"] = summary.segments;
  out["largest_segment_keyframes"] = summary.largest_segment_keyframes;
  out["largest_part_ratio"] = summary.LargestPartRatio();
  out["prior_links"] = summary.prior_links;
  out["labels"] = summary.labels;
  out["synthetic_views"] = summary.synthetic_views;
  out["synthetic_view_bytes"] = summary.synthetic_view_bytes;
  out["photo_feature_keyframes"] = summary.photo_feature_keyframes;
  out["photo_feature_bytes"] = summary.photo_feature_bytes;
  out["size_bytes"] = summary.size_bytes;
  out["links"] = {{"odometry", summary.odometry_links},
                  {"loop", summary.loop_closures},
                  {"relocalisation", summary.relocalisation_links},
                  {"user", summary.user_links},
                  {"prior", summary.prior_links},
                  {"inactive", summary.inactive_links}};
  if (summary.has_bounding_box) {
    out["bounding_box"] = {
        {"min", {summary.bbox_min.x(), summary.bbox_min.y(), summary.bbox_min.z()}},
        {"max", {summary.bbox_max.x(), summary.bbox_max.y(), summary.bbox_max.z()}}};
  } else {
    out["bounding_box"] = nullptr;
  }
  nlohmann::json names = nlohmann::json::array();
  for (const store::LabelRecord& label : labels) names.push_back(label.name);
  out["label_names"] = names;
  out["coverage_share"] = coverage ? nlohmann::json(coverage->share()) : nlohmann::json();
  out["session_list"] = SessionsJson(model.Sessions());
  return out;
}

void PrintInfo(const std::string& path, const store::Model& model,
               const store::ModelSummary& summary, const std::vector<store::LabelRecord>& labels,
               const std::optional<identify::ModelCoverage>& coverage) {
  std::cout << "model          " << path << " (schema " << summary.schema_version << ", "
            << std::fixed << std::setprecision(1) << summary.size_bytes / 1e6 << " MB)\n";
  std::cout << "sessions       " << summary.sessions << "\n";
  for (const store::SessionRecord& session : model.Sessions()) {
    std::cout << "  #" << session.id.value() << " " << store::SessionEndName(session.end_state)
              << "  " << (session.source.empty() ? "(no source)" : session.source);
    if (!session.device_name.empty()) std::cout << "  " << session.device_name;
    std::cout << "\n";
  }
  std::cout << "keyframes      " << summary.keyframes << " in " << summary.segments
            << " segment(s)";
  if (summary.segments > 1) {
    std::cout << ", the largest " << summary.largest_segment_keyframes << " keyframes";
  }
  std::cout << "\n";
  std::cout << "links          " << summary.odometry_links << " odometry, " << summary.loop_closures
            << " loop closure, " << summary.relocalisation_links << " relocalisation, "
            << summary.user_links << " user, " << summary.prior_links << " prior";
  if (summary.inactive_links > 0) {
    std::cout << "; " << summary.inactive_links << " switched off as inconsistent";
  }
  std::cout << "\n";
  std::cout << "labels         " << summary.labels;
  for (size_t i = 0; i < labels.size(); ++i) std::cout << (i ? ", " : "  ") << labels[i].name;
  std::cout << "\n";
  if (summary.synthetic_views > 0) {
    std::cout << "synthetic      " << summary.synthetic_views << " views for photos ("
              << std::setprecision(1) << summary.synthetic_view_bytes / 1e6
              << " MB; 'sightmap synthesize')\n";
  }
  if (summary.photo_feature_keyframes > 0) {
    std::cout << "photo features " << summary.photo_feature_keyframes
              << " keyframes with RootSIFT (" << std::setprecision(1)
              << summary.photo_feature_bytes / 1e6 << " MB)\n";
  }
  if (coverage) {
    std::cout << "coverage       " << coverage->seen << " of " << coverage->open
              << " open directions around the labels seen (" << std::setprecision(0)
              << 100.0 * coverage->share() << "%; 'sightmap coverage' for each)\n";
  }
  if (summary.has_bounding_box) {
    std::cout << std::setprecision(2) << "bounding box   [" << summary.bbox_min.x() << ", "
              << summary.bbox_min.y() << ", " << summary.bbox_min.z() << "] .. ["
              << summary.bbox_max.x() << ", " << summary.bbox_max.y() << ", "
              << summary.bbox_max.z() << "] m\n";
  }
}

}  // namespace

int RunInfo(int argc, char** argv) {
  CLI::App app("Report what a model holds: sessions, keyframes, links by type, labels, size.",
               "sightmap info");
  std::string path;
  bool json = false;
  AddModelArgument(app, path);
  bool upgrade = false;
  app.add_flag("--json", json, "print one JSON object (stable keys) instead of text");
  app.add_flag("--upgrade", upgrade,
               "upgrade a model written by an older sightmap, in place: this one's schema, and the "
               "RootSIFT features photos are matched with for keyframes that lack them (so "
               "that locate and serve need not extract them at every start)");
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (const int code = RequireModelArgument(app, path); code >= 0) return code;

  store::ModelOptions options;
  options.read_only = !upgrade;
  options.create_if_missing = false;
  store::Model model = store::Model::Open(path, options);
  // One transaction a keyframe: an interrupted upgrade keeps what it stored and goes on from there.
  if (upgrade) {
    mapping::AddMissingPhotoFeatures(&model, mapping::PhotoFeatureExtraction(),
                                     TenthsProgress("upgrade: photo features", "keyframes"));
  }
  const store::ModelSummary summary = model.Summary();
  const std::vector<store::LabelRecord> labels = model.Labels();
  // How much of what people could photograph the walk saw (identify/coverage.h); it reads every
  // keyframe's depth, so only when there are labels to judge.
  std::optional<identify::ModelCoverage> coverage;
  if (!labels.empty()) coverage = identify::ComputeCoverage(model);
  if (json) {
    std::cout << InfoJson(model, summary, labels, coverage).dump(2) << "\n";
  } else {
    PrintInfo(path, model, summary, labels, coverage);
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
