// sightmap coverage MODEL [--json] [--png FILE]: from which directions the keyframes saw each
// labelled appliance, and which open directions they missed (identify/coverage.h), so the manager
// walks back to what a phone photo could not be matched against.
#include <iomanip>
#include <iostream>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "identify/coverage.h"
#include "render/image_file.h"
#include "store/model.h"

namespace sightmap::cli {
namespace {

// "150-210, 330-30": the open sectors not seen, merged where adjacent (across 0) [deg].
std::string MissingBearings(const identify::LabelCoverage& label) {
  const size_t n = label.sectors.size();
  const auto missing = [&label, n](size_t s) {
    const identify::SectorCoverage& sector = label.sectors[s % n];
    return sector.open && !sector.seen();
  };
  // Start after a sector that is not missing, so a run across 0 degrees is one run.
  size_t start = 0;
  while (start < n && missing(start)) ++start;
  if (start == n) return "all round";
  std::string text;
  for (size_t i = 1; i <= n; ++i) {
    const size_t s = start + i;
    if (!missing(s) || missing(s - 1)) continue;
    size_t end = s;
    while (missing(end + 1)) ++end;
    if (!text.empty()) text += ", ";
    text += std::to_string(static_cast<int>(label.sectors[s % n].from_deg)) + "-" +
            std::to_string(static_cast<int>(label.sectors[end % n].to_deg)) + " deg";
  }
  return text;
}

void PrintText(const identify::ModelCoverage& coverage, const identify::CoverageOptions& options) {
  std::cout << "coverage       " << coverage.seen << " of " << coverage.open
            << " open directions seen (" << std::fixed << std::setprecision(0)
            << 100.0 * coverage.share() << "%), " << options.sectors << " sectors of "
            << 360 / options.sectors << " deg, " << std::setprecision(1) << options.min_distance_m
            << "-" << options.max_distance_m << " m away\n";
  for (const identify::LabelCoverage& label : coverage.labels) {
    std::cout << "  " << std::left << std::setw(24) << label.name << std::right << std::setw(3)
              << label.seen << "/" << std::left << std::setw(3) << label.open << std::right;
    if (label.keyframes == 0) {
      std::cout << "  never seen";
    } else if (label.seen < label.open) {
      std::cout << "  missing " << MissingBearings(label);
    } else if (label.open == 0) {
      std::cout << "  seen only from outside " << std::setprecision(1) << options.min_distance_m
                << "-" << options.max_distance_m << " m";
    } else {
      std::cout << "  complete";
    }
    std::cout << "\n";
  }
  if (coverage.labels.empty()) {
    std::cout << "  no labels: add some with 'sightmap label' to see their coverage\n";
  }
}

}  // namespace

int RunCoverage(int argc, char** argv) {
  CLI::App app(
      "Report from which directions the keyframes saw each labelled appliance, and which open "
      "directions they missed (walk back there).",
      "sightmap coverage");
  std::string path;
  bool json = false;
  std::string png_path;
  identify::CoverageOptions options;
  AddModelArgument(app, path);
  app.add_flag("--json", json, "print one JSON object (stable keys) instead of text");
  app.add_option("--png", png_path,
                 "write a floor plan: per appliance its sectors, green seen, red missing");
  app.add_option("--sectors", options.sectors, "directions around each appliance")
      ->capture_default_str()
      ->check(Within(4, 360));
  app.add_option("--min-distance", options.min_distance_m, "nearest standpoint that counts [m]")
      ->capture_default_str()
      ->check(Within(0.1, 20, "m"));
  app.add_option("--max-distance", options.max_distance_m, "furthest standpoint that counts [m]")
      ->capture_default_str()
      ->check(Within(0.2, 30, "m"));
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (const int code = RequireModelArgument(app, path); code >= 0) return code;
  if (!(options.max_distance_m > options.min_distance_m)) {
    PrintError("--max-distance must be greater than --min-distance");
    return kExitUsage;
  }
  if (!png_path.empty()) CheckOutputFile(png_path, "--png");

  store::ModelOptions model_options;
  model_options.read_only = true;
  const store::Model model = store::Model::Open(path, model_options);
  // A 3,000-keyframe model takes a while to read.
  const identify::ModelCoverage coverage =
      identify::ComputeCoverage(model, options, TenthsProgress("coverage", "keyframes"));
  if (!png_path.empty()) {
    render::WriteImageAtomically(png_path, identify::DrawCoverage(coverage));
  }
  if (json) {
    std::cout << identify::CoverageToJson(coverage).dump(2) << "\n";
  } else {
    PrintText(coverage, options);
    if (!png_path.empty()) std::cout << "floor plan     " << png_path << "\n";
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
