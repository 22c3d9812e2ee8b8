// sightmap synthesize MODEL [--json] [--all-sectors] [--grid M] [--clear] [--images DIR]: renders
// views of each labelled appliance from the open directions the walk missed (and from a grid of
// free floor) (synthesis/view_synthesis.h) and
// stores them as synthetic views, which `locate` and `serve` match photos against; mapping never
// reads them.
#include <cstdlib>
#include <iomanip>
#include <iostream>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "render/image_file.h"
#include "store/model.h"
#include "synthesis/view_synthesis.h"

namespace sightmap::cli {

int RunSynthesize(int argc, char** argv) {
  CLI::App app(
      "Render views of each labelled appliance from the open directions the walk missed, and "
      "store them so phone photos taken from there are located (replaces earlier ones).",
      "sightmap synthesize");
  std::string path;
  bool json = false;
  bool clear = false;
  synthesis::ViewSynthesisOptions options;
  bool print_config = false;
  AddModelArgument(app, path);
  app.add_flag("--json", json, "print one JSON object (stable keys) instead of text");
  app.add_flag("--clear", clear, "only remove the model's synthetic views");
  bool all_sectors = false;
  app.add_flag("--all-sectors", all_sectors,
               "also render the open directions keyframes saw (default: only those they missed)");
  app.add_option("--grid", options.grid_step_m,
                 "also render from standpoints on a grid of free floor this far apart, towards "
                 "each label in reach the walk did not see from there [m] (default 0: none)")
      ->check(CLI::Validator(
          [](const std::string& text) {
            const double step = std::strtod(text.c_str(), nullptr);
            return step == 0.0 || step >= 0.1 ? std::string()
                                              : "must be 0 (no grid) or at least 0.1 m";
          },
          "M"));
  std::string images_dir;
  app.add_option("--images", images_dir,
                 "also write each stored view as DIR/view-ID.png, to look at what was rendered");
  AddConfigOptions(app, options, print_config);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (all_sectors) options.missing_sectors_only = false;
  if (print_config) return PrintConfig(options);
  if (const int code = RequireModelArgument(app, path); code >= 0) return code;
  if (!images_dir.empty()) CheckOutputFolder(images_dir, "--images");

  store::ModelOptions model_options;
  model_options.create_if_missing = false;
  store::Model model = store::Model::Open(path, model_options);
  if (clear) {
    const int64_t removed = model.DeleteSyntheticViews();
    if (json) {
      std::cout << nlohmann::json{{"deleted", removed}}.dump(2) << "\n";
    } else {
      std::cout << "removed        " << removed << " synthetic views\n";
    }
    return kExitSuccess;
  }
  const synthesis::SynthesisReport report =
      synthesis::SynthesizeViews(model, options, TenthsProgress("synthesize", "views"));
  if (!images_dir.empty()) {
    for (const store::SyntheticViewRecord& view : model.SyntheticViews()) {
      render::WriteImageAtomically(images_dir + "/view-" + std::to_string(view.id.value()) + ".png",
                                   model.LoadSyntheticColor(view.id));
    }
  }
  if (json) {
    std::cout << synthesis::ToJson(report).dump(2) << "\n";
    return kExitSuccess;
  }
  std::cout << "standpoints    " << report.standpoints << " around " << report.labels
            << " labels (open directions " << (options.missing_sectors_only ? "not seen" : "all")
            << ")";
  if (options.grid_step_m > 0.0) {
    std::cout << ", " << report.grid_standpoints << " of them on a " << options.grid_step_m
              << " m grid of free floor";
  }
  std::cout << "\n"
            << "written        " << report.written << " synthetic views, " << std::fixed
            << std::setprecision(1) << report.bytes / 1e6 << " MB";
  if (report.deleted > 0) std::cout << " (replacing " << report.deleted << ")";
  std::cout << "\nrefused        " << report.refused << "\n";
  for (const std::string& line : report.refusals) std::cout << "  " << line << "\n";
  std::cout << "time           " << std::setprecision(1) << report.seconds << " s\n";
  return kExitSuccess;
}

}  // namespace sightmap::cli
