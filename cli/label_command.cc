// sightmap label add|import|list|remove|export --model M ...: the appliance labels of a model (see
// identify/labels.h). Label commands never create a model: a mistyped path is an error, not a new
// empty file.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "core/check.h"
#include "identify/labels.h"
#include "store/label_files.h"
#include "store/model.h"

namespace sightmap::cli {
namespace {

// "1.5,-2,3" to exactly `count` finite numbers; `flag` and `form` name the option in the error.
std::vector<double> ParseNumbers(const std::string& text, int count, const std::string& flag,
                                 const std::string& form) {
  std::vector<double> values;
  const char* cursor = text.c_str();
  for (int i = 0; i < count; ++i) {
    if (i > 0) {
      if (*cursor != ',') break;
      ++cursor;
    }
    char* end = nullptr;
    errno = 0;
    const double value = std::strtod(cursor, &end);
    if (end == cursor || errno == ERANGE || !std::isfinite(value)) break;
    values.push_back(value);
    cursor = end;
  }
  if (static_cast<int>(values.size()) != count || *cursor != '\0') {
    SIGHTMAP_THROW(InvalidArgument, flag << " must be " << form << " (numbers separated by commas, "
                                         << "no spaces), got '" << text << "'");
  }
  return values;
}

store::Model OpenExisting(const std::string& path, bool read_only) {
  store::ModelOptions options;
  options.read_only = read_only;
  options.create_if_missing = false;
  return store::Model::Open(path, options);
}

std::string FormatPoint(const Eigen::Vector3d& p) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << "[" << p.x() << ", " << p.y() << ", " << p.z()
      << "]";
  return out.str();
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string joined;
  for (const std::string& name : names) joined += (joined.empty() ? "" : ", ") + name;
  return joined;
}

void PrintImportReport(const identify::LabelImportReport& report, const std::string& from) {
  std::cout << "imported " << report.created.size() + report.replaced.size() << " label(s), "
            << report.points << " point(s) from " << from << "\n";
  if (!report.created.empty()) std::cout << "  created   " << JoinNames(report.created) << "\n";
  if (!report.replaced.empty()) {
    std::cout << "  replaced  " << JoinNames(report.replaced)
              << " (existing labels of these names: their points were replaced)\n";
  }
  if (report.clicked_points > 0 || !report.not_clicked.empty()) {
    std::cout << "  clicked   " << report.clicked_points << " of " << report.points
              << " point(s) placed on a keyframe's surface\n";
  }
  if (!report.not_clicked.empty()) {
    std::cout << "  as given  " << JoinNames(report.not_clicked)
              << " (no keyframe shows their point: kept where the file puts it)\n";
  }
}

}  // namespace

int RunLabel(int argc, char** argv) {
  CLI::App app("The appliance labels of a model: add points, import, list, remove, export.",
               "sightmap label");
  app.require_subcommand(1);
  std::string model_path;
  auto add_model = [&model_path](CLI::App* command) {
    command->add_option("--model", model_path, "the model's SQLite file (must exist)")->required();
  };

  CLI::App* add = app.add_subcommand(
      "add", "add a point to label --name (created if new): a keyframe pixel or a world point");
  std::string name;
  std::optional<std::string> type;
  int64_t keyframe_id = 0;
  std::string pixel_text;
  std::string point_text;
  identify::PixelLabelOptions pixel_options;
  add_model(add);
  add->add_option("--name", name, "the appliance's label (unique in the model)")->required();
  add->add_option("--type", type,
                  "lamp, projector, ... (new labels: 'appliance'; existing ones keep theirs)");
  CLI::Option* keyframe_option =
      add->add_option("--keyframe", keyframe_id, "the keyframe clicked on ('sightmap info')");
  CLI::Option* pixel_option =
      add->add_option("--pixel", pixel_text, "U,V: the clicked pixel of --keyframe [px]");
  CLI::Option* point_option =
      add->add_option("--point", point_text, "X,Y,Z: a point in world coordinates [m]");
  add->add_option("--max-depth-search", pixel_options.max_depth_search_px,
                  "when the pixel has no depth, use the nearest within this radius [px]")
      ->check(Within(0, 1000, "px"))
      ->capture_default_str();
  keyframe_option->needs(pixel_option);
  pixel_option->needs(keyframe_option);
  point_option->excludes(keyframe_option);
  point_option->excludes(pixel_option);

  CLI::App* import = app.add_subcommand(
      "import",
      "label appliances from CloudCompare point lists (FILE..., one per appliance, named after "
      "the file) or from a simulator scene (--from-scene appliances.json); labels of the same "
      "name get the new points");
  std::vector<std::string> files;
  std::string scene_path;
  add_model(import);
  import->add_option("FILE", files, "point-list files (x y z per line)");
  import->add_option("--from-scene", scene_path, "a scene's appliances.json ('sim generate')");
  bool as_clicked = false;
  import->add_flag("--as-clicked", as_clicked,
                   "with --from-scene: place each point where a user would click it, on the "
                   "surface a keyframe shows nearest the point, seen from the side the walk saw "
                   "it from (a scene's point may be its appliance's centre, inside it)");
  import->add_option("--type", type,
                     "with FILE...: the labels' type (new labels: 'appliance'; existing keep "
                     "theirs)");

  CLI::App* list = app.add_subcommand("list", "list labels with their points (world, metres)");
  bool json = false;
  add_model(list);
  list->add_flag("--json", json,
                 "one JSON object: {\"labels\": [{\"name\", \"type\", \"points\": [[x, y, z]], "
                 "\"point_sources\"}]}");

  CLI::App* remove = app.add_subcommand("remove", "delete label --name");
  add_model(remove);
  remove->add_option("--name", name, "the label to delete")->required();

  CLI::App* export_labels =
      app.add_subcommand("export", "write one point-list file per label to --dir");
  std::string dir;
  add_model(export_labels);
  export_labels->add_option("--dir", dir, "output folder (created)")->required();

  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;

  if (add->parsed()) {
    if (!point_option->count() && !pixel_option->count()) {
      PrintError("label add needs a point: --keyframe ID --pixel U,V or --point X,Y,Z");
      return kExitUsage;
    }
    std::optional<Eigen::Vector3d> world;
    std::optional<Eigen::Vector2d> pixel;
    if (point_option->count()) {
      const std::vector<double> xyz = ParseNumbers(point_text, 3, "--point", "X,Y,Z");
      world = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    } else {
      const std::vector<double> uv = ParseNumbers(pixel_text, 2, "--pixel", "U,V");
      pixel = Eigen::Vector2d(uv[0], uv[1]);
    }
    store::Model model = OpenExisting(model_path, /*read_only=*/false);
    std::ostringstream from;
    store::LabelPoint point;
    if (world) {
      point = identify::LabelPointFromWorld(*world);
      from << "typed";
    } else {
      const identify::PixelLabelPoint clicked =
          identify::LabelPointFromPixel(model, KeyframeId(keyframe_id), *pixel, pixel_options);
      point = clicked.point;
      from << "keyframe " << keyframe_id << " pixel " << pixel->x() << "," << pixel->y()
           << ", depth " << std::fixed << std::setprecision(3) << clicked.depth_m << " m";
      if (clicked.depth_offset_px > 0.0) {
        from << " borrowed from pixel " << clicked.depth_pixel.x() << "," << clicked.depth_pixel.y()
             << " (" << std::setprecision(1) << clicked.depth_offset_px
             << " px away: the clicked pixel has none)";
      }
    }
    const bool existed = model.FindLabel(name).has_value();
    const store::LabelRecord label = identify::AddPointsToLabel(model, name, {point}, type);
    std::cout << (existed ? "added to " : "created ") << "label '" << label.name << "' ("
              << label.type << "): point " << label.points.size() << " at "
              << FormatPoint(label.points.back().world) << " m, " << from.str() << "\n";
    return kExitSuccess;
  }

  if (import->parsed()) {
    if (files.empty() == scene_path.empty()) {
      PrintError("label import takes point-list FILE... or --from-scene FILE, not " +
                 std::string(files.empty() ? "neither" : "both"));
      return kExitUsage;
    }
    if (as_clicked && scene_path.empty()) {
      PrintError("--as-clicked applies to --from-scene; point-list files are taken as given");
      return kExitUsage;
    }
    if (!scene_path.empty() && type) {
      PrintError("--type applies to point-list files; a scene file gives each appliance's type");
      return kExitUsage;
    }
    store::Model model = OpenExisting(model_path, /*read_only=*/false);
    if (!scene_path.empty()) {
      const std::optional<identify::ClickOptions> click =
          as_clicked ? std::optional<identify::ClickOptions>(identify::ClickOptions())
                     : std::nullopt;
      PrintImportReport(identify::ImportSceneLabels(model, scene_path, click), scene_path);
    } else {
      PrintImportReport(identify::ImportPointListLabels(model, files, type),
                        std::to_string(files.size()) + " file(s)");
    }
    return kExitSuccess;
  }

  if (list->parsed()) {
    const store::Model model = OpenExisting(model_path, /*read_only=*/true);
    const std::vector<store::LabelRecord> labels = model.Labels();
    if (json) {
      std::cout << identify::LabelsToJson(labels).dump(2) << "\n";
      return kExitSuccess;
    }
    if (labels.empty()) {
      std::cout << "no labels: add one with 'sightmap label add' or 'sightmap label import'\n";
    }
    for (const store::LabelRecord& label : labels) {
      std::cout << label.name << " (" << label.type << "), " << label.points.size() << " point(s):";
      for (const store::LabelPoint& point : label.points)
        std::cout << " " << FormatPoint(point.world);
      std::cout << " m\n";
    }
    return kExitSuccess;
  }

  if (remove->parsed()) {
    store::Model model = OpenExisting(model_path, /*read_only=*/false);
    const std::optional<store::LabelRecord> label = model.FindLabel(name);
    SIGHTMAP_CHECK(label, "no label named '" << name << "' in " << model_path
                                             << ": 'sightmap label list --model " << model_path
                                             << "' lists them");
    model.DeleteLabel(label->id);
    std::cout << "removed label '" << name << "' (" << label->points.size() << " point(s))\n";
    return kExitSuccess;
  }

  CheckOutputFolder(dir, "--dir");
  const store::Model model = OpenExisting(model_path, /*read_only=*/true);
  const int count = store::ExportLabels(model, dir);
  std::cout << "labels         " << dir << ": " << count << " files\n";
  return kExitSuccess;
}

}  // namespace sightmap::cli
