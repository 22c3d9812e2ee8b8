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

// The options of every `label` subcommand (each reads its own).
struct LabelArgs {
  std::string model_path;
  std::string name;
  std::optional<std::string> type;
  // add: a keyframe pixel or a world point
  int64_t keyframe_id = 0;
  std::optional<std::string> pixel_text;
  std::optional<std::string> point_text;
  identify::PixelLabelOptions pixel_options;
  // import: point-list files or a scene
  std::vector<std::string> files;
  std::string scene_path;
  bool as_clicked = false;
  bool json = false;  // list
  std::string dir;    // export
};

void AddModelOption(CLI::App* command, LabelArgs* args) {
  command->add_option("--model", args->model_path, "the model's SQLite file (must exist)")
      ->required();
}

CLI::App* DeclareAdd(CLI::App& app, LabelArgs* args) {
  CLI::App* add = app.add_subcommand(
      "add", "add a point to label --name (created if new): a keyframe pixel or a world point");
  AddModelOption(add, args);
  add->add_option("--name", args->name, "the appliance's label (unique in the model)")->required();
  add->add_option("--type", args->type,
                  "lamp, projector, ... (new labels: 'appliance'; existing ones keep theirs)");
  CLI::Option* keyframe_option =
      add->add_option("--keyframe", args->keyframe_id, "the keyframe clicked on ('sightmap info')");
  CLI::Option* pixel_option =
      add->add_option("--pixel", args->pixel_text, "U,V: the clicked pixel of --keyframe [px]");
  CLI::Option* point_option =
      add->add_option("--point", args->point_text, "X,Y,Z: a point in world coordinates [m]");
  add->add_option("--max-depth-search", args->pixel_options.max_depth_search_px,
                  "when the pixel has no depth, use the nearest within this radius [px]")
      ->check(Within(0, 1000, "px"))
      ->capture_default_str();
  keyframe_option->needs(pixel_option);
  pixel_option->needs(keyframe_option);
  point_option->excludes(keyframe_option);
  point_option->excludes(pixel_option);
  return add;
}

CLI::App* DeclareImport(CLI::App& app, LabelArgs* args) {
  CLI::App* import = app.add_subcommand(
      "import",
      "label appliances from CloudCompare point lists (FILE..., one per appliance, named after "
      "the file) or from a simulator scene (--from-scene appliances.json); labels of the same "
      "name get the new points");
  AddModelOption(import, args);
  import->add_option("FILE", args->files, "point-list files (x y z per line)");
  import->add_option("--from-scene", args->scene_path,
                     "a scene's appliances.json ('sim generate')");
  import->add_flag("--as-clicked", args->as_clicked,
                   "with --from-scene: place each point where a user would click it, on the "
                   "surface a keyframe shows nearest the point, seen from the side the walk saw "
                   "it from (a scene's point may be its appliance's centre, inside it)");
  import->add_option("--type", args->type,
                     "with FILE...: the labels' type (new labels: 'appliance'; existing keep "
                     "theirs)");
  return import;
}

int LabelAdd(const LabelArgs& args) {
  if (!args.point_text && !args.pixel_text) {
    PrintError("label add needs a point: --keyframe ID --pixel U,V or --point X,Y,Z");
    return kExitUsage;
  }
  std::optional<Eigen::Vector3d> world;
  std::optional<Eigen::Vector2d> pixel;
  if (args.point_text) {
    const std::vector<double> xyz = ParseNumbers(*args.point_text, 3, "--point", "X,Y,Z");
    world = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
  } else {
    const std::vector<double> uv = ParseNumbers(*args.pixel_text, 2, "--pixel", "U,V");
    pixel = Eigen::Vector2d(uv[0], uv[1]);
  }
  store::Model model = OpenExisting(args.model_path, /*read_only=*/false);
  std::ostringstream from;
  store::LabelPoint point;
  if (world) {
    point = identify::LabelPointFromWorld(*world);
    from << "typed";
  } else {
    const identify::PixelLabelPoint clicked = identify::LabelPointFromPixel(
        model, KeyframeId(args.keyframe_id), *pixel, args.pixel_options);
    point = clicked.point;
    from << "keyframe " << args.keyframe_id << " pixel " << pixel->x() << "," << pixel->y()
         << ", depth " << std::fixed << std::setprecision(3) << clicked.depth_m << " m";
    if (clicked.depth_offset_px > 0.0) {
      from << " borrowed from pixel " << clicked.depth_pixel.x() << "," << clicked.depth_pixel.y()
           << " (" << std::setprecision(1) << clicked.depth_offset_px
           << " px away: the clicked pixel has none)";
    }
  }
  const bool existed = model.FindLabel(args.name).has_value();
  const store::LabelRecord label = identify::AddPointsToLabel(model, args.name, {point}, args.type);
  std::cout << (existed ? "added to " : "created ") << "label '" << label.name << "' ("
            << label.type << "): point " << label.points.size() << " at "
            << FormatPoint(label.points.back().world) << " m, " << from.str() << "\n";
  return kExitSuccess;
}

int LabelImport(const LabelArgs& args) {
  if (args.files.empty() == args.scene_path.empty()) {
    PrintError("label import takes point-list FILE... or --from-scene FILE, not " +
               std::string(args.files.empty() ? "neither" : "both"));
    return kExitUsage;
  }
  if (args.as_clicked && args.scene_path.empty()) {
    PrintError("--as-clicked applies to --from-scene; point-list files are taken as given");
    return kExitUsage;
  }
  if (!args.scene_path.empty() && args.type) {
    PrintError("--type applies to point-list files; a scene file gives each appliance's type");
    return kExitUsage;
  }
  store::Model model = OpenExisting(args.model_path, /*read_only=*/false);
  if (!args.scene_path.empty()) {
    const std::optional<identify::ClickOptions> click =
        args.as_clicked ? std::optional<identify::ClickOptions>(identify::ClickOptions())
                        : std::nullopt;
    PrintImportReport(identify::ImportSceneLabels(model, args.scene_path, click), args.scene_path);
  } else {
    PrintImportReport(identify::ImportPointListLabels(model, args.files, args.type),
                      std::to_string(args.files.size()) + " file(s)");
  }
  return kExitSuccess;
}

int LabelList(const LabelArgs& args) {
  const store::Model model = OpenExisting(args.model_path, /*read_only=*/true);
  const std::vector<store::LabelRecord> labels = model.Labels();
  if (args.json) {
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

int LabelRemove(const LabelArgs& args) {
  store::Model model = OpenExisting(args.model_path, /*read_only=*/false);
  const std::optional<store::LabelRecord> label = model.FindLabel(args.name);
  SIGHTMAP_CHECK(label, "no label named '" << args.name << "' in " << args.model_path
                                           << ": 'sightmap label list --model " << args.model_path
                                           << "' lists them");
  model.DeleteLabel(label->id);
  std::cout << "removed label '" << args.name << "' (" << label->points.size() << " point(s))\n";
  return kExitSuccess;
}

int LabelExport(const LabelArgs& args) {
  CheckOutputFolder(args.dir, "--dir");
  const store::Model model = OpenExisting(args.model_path, /*read_only=*/true);
  const int count = store::ExportLabels(model, args.dir);
  std::cout << "labels         " << args.dir << ": " << count << " files\n";
  return kExitSuccess;
}

}  // namespace

int RunLabel(int argc, char** argv) {
  CLI::App app("The appliance labels of a model: add points, import, list, remove, export.",
               "sightmap label");
  app.require_subcommand(1);
  LabelArgs args;
  CLI::App* add = DeclareAdd(app, &args);
  CLI::App* import = DeclareImport(app, &args);
  CLI::App* list = app.add_subcommand("list", "list labels with their points (world, metres)");
  AddModelOption(list, &args);
  list->add_flag("--json", args.json,
                 "one JSON object: {\"labels\": [{\"name\", \"type\", \"points\": [[x, y, z]], "
                 "\"point_sources\"}]}");
  CLI::App* remove = app.add_subcommand("remove", "delete label --name");
  AddModelOption(remove, &args);
  remove->add_option("--name", args.name, "the label to delete")->required();
  CLI::App* export_labels =
      app.add_subcommand("export", "write one point-list file per label to --dir");
  AddModelOption(export_labels, &args);
  export_labels->add_option("--dir", args.dir, "output folder (created)")->required();

  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (add->parsed()) return LabelAdd(args);
  if (import->parsed()) return LabelImport(args);
  if (list->parsed()) return LabelList(args);
  if (remove->parsed()) return LabelRemove(args);
  return LabelExport(args);
}

}  // namespace sightmap::cli
