#include "identify/labels.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <utility>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/input_file.h"
#include "core/options_json.h"
#include "identify/visibility.h"
#include "store/label_files.h"

namespace sightmap::identify {
namespace {

std::string TypeOrDefault(const std::optional<std::string>& type) {
  return type && !type->empty() ? *type : std::string(kDefaultLabelType);
}

// Writes `labels` (created or replacing the label of the same name). The store has no transaction
// spanning several labels, so the caller validates everything first, and a write that still fails
// (disk full, a locked file) is undone here by restoring what was there before.
LabelImportReport WriteLabels(store::Model& model, std::vector<store::LabelRecord> labels,
                              bool keep_existing_type) {
  struct Written {
    LabelId id;
    std::optional<store::LabelRecord> before;
  };
  std::vector<Written> written;
  LabelImportReport report;
  try {
    for (store::LabelRecord& label : labels) {
      std::optional<store::LabelRecord> existing = model.FindLabel(label.name);
      if (existing) {
        label.id = existing->id;
        if (keep_existing_type) label.type = existing->type;
        model.UpdateLabel(label);
        written.push_back({label.id, std::move(existing)});
        report.replaced.push_back(label.name);
      } else {
        written.push_back({model.AddLabel(label), std::nullopt});
        report.created.push_back(label.name);
      }
      report.points += static_cast<int>(label.points.size());
    }
  } catch (...) {
    for (auto it = written.rbegin(); it != written.rend(); ++it) {
      try {
        if (it->before) {
          model.UpdateLabel(*it->before);
        } else {
          model.DeleteLabel(it->id);
        }
      } catch (...) {
        // The original error says what went wrong; a failing undo has the same cause.
      }
    }
    throw;
  }
  std::sort(report.created.begin(), report.created.end());
  std::sort(report.replaced.begin(), report.replaced.end());
  return report;
}

// Refuses two labels of the same name in one import, naming where each came from.
void CheckUniqueNames(const std::vector<store::LabelRecord>& labels,
                      const std::vector<std::string>& origins) {
  std::map<std::string, size_t> seen;
  for (size_t i = 0; i < labels.size(); ++i) {
    const auto [it, inserted] = seen.emplace(labels[i].name, i);
    SIGHTMAP_CHECK(inserted, "label '" << labels[i].name << "' would come from both "
                                       << origins[it->second] << " and " << origins[i]
                                       << ": rename one of them");
  }
}

Eigen::Vector3d ParseScenePoint(const nlohmann::json& value, const std::string& where) {
  SIGHTMAP_CHECK(value.is_array() && value.size() == 3,
                 where << " is not [x, y, z]: fix the scene file");
  Eigen::Vector3d point;
  for (int i = 0; i < 3; ++i) {
    const nlohmann::json& coordinate = value[static_cast<size_t>(i)];
    SIGHTMAP_CHECK(coordinate.is_number() && std::isfinite(coordinate.get<double>()),
                   where << " is not three finite numbers [m]: fix the scene file");
    point[i] = coordinate.get<double>();
  }
  return point;
}

}  // namespace

bool PixelLabelOptions::Check(std::string* error) const {
  auto fail = [error](const char* message) {
    if (error) *error = message;
    return false;
  };
  if (!(max_depth_search_px >= 0.0 && max_depth_search_px <= 100.0)) {
    return fail("max_depth_search_px must be in [0, 100] px");
  }
  if (!(max_depth_m > 0.0)) return fail("max_depth_m must be positive");
  return true;
}

PixelLabelPoint LabelPointFromPixel(const store::Model& model, KeyframeId keyframe,
                                    const Eigen::Vector2d& pixel,
                                    const PixelLabelOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(keyframe.valid(), "keyframe ids start at 1: run 'sightmap info' on the model");
  const store::KeyframeInfo info = model.Keyframe(keyframe);  // throws naming the model when absent
  const Intrinsics& k = info.intrinsics;
  const long u0 = std::isfinite(pixel.x()) ? std::lround(pixel.x()) : -1;
  const long v0 = std::isfinite(pixel.y()) ? std::lround(pixel.y()) : -1;
  SIGHTMAP_CHECK(u0 >= 0 && u0 < k.width && v0 >= 0 && v0 < k.height,
                 "pixel " << pixel.x() << "," << pixel.y() << " is outside keyframe "
                          << keyframe.value() << "'s " << k.width << "x" << k.height
                          << " image: pick u in [0, " << k.width - 1 << "], v in [0, "
                          << k.height - 1 << "]");
  const std::optional<PixelLabelPoint> point =
      LabelPointFromDepth(info, model.LoadDepth(keyframe), pixel, options);
  SIGHTMAP_CHECK(point, "pixel " << pixel.x() << "," << pixel.y() << " of keyframe "
                                 << keyframe.value() << " has no depth within "
                                 << options.max_depth_search_px
                                 << " px: click on a surface the sensor saw, or type the "
                                    "point with --point X,Y,Z");
  return *point;
}

namespace {

// A stored depth image that does not fit its keyframe's intrinsics is a damaged model.
void CheckDepthFits(const store::KeyframeInfo& keyframe, const cv::Mat& depth) {
  const Intrinsics& k = keyframe.intrinsics;
  SIGHTMAP_CHECK(depth.type() == CV_16UC1 && depth.cols == k.width && depth.rows == k.height,
                 "keyframe " << keyframe.id.value() << "'s depth image is " << depth.cols << "x"
                             << depth.rows << ", its intrinsics " << k.width << "x" << k.height
                             << ": the model is inconsistent, re-map it");
}

}  // namespace

std::optional<PixelLabelPoint> LabelPointFromDepth(const store::KeyframeInfo& keyframe,
                                                   const cv::Mat& depth,
                                                   const Eigen::Vector2d& pixel,
                                                   const PixelLabelOptions& options) {
  CheckDepthFits(keyframe, depth);
  const Intrinsics& k = keyframe.intrinsics;
  const long u0 = std::isfinite(pixel.x()) ? std::lround(pixel.x()) : -1;
  const long v0 = std::isfinite(pixel.y()) ? std::lround(pixel.y()) : -1;
  if (u0 < 0 || u0 >= k.width || v0 < 0 || v0 >= k.height) return std::nullopt;

  // The nearest pixel with a usable depth, by pixel distance; ties go to the first in scan order,
  // so the answer does not depend on anything but the image.
  const int radius = static_cast<int>(std::floor(options.max_depth_search_px));
  const double max_distance2 = options.max_depth_search_px * options.max_depth_search_px;
  const double max_depth_mm = options.max_depth_m * 1000.0;
  int best_u = -1;
  int best_v = -1;
  double best_distance2 = max_distance2 + 1.0;
  for (int v = std::max(0L, v0 - radius); v <= std::min<long>(k.height - 1, v0 + radius); ++v) {
    const auto* row = depth.ptr<uint16_t>(v);
    for (int u = std::max(0L, u0 - radius); u <= std::min<long>(k.width - 1, u0 + radius); ++u) {
      const double distance2 = static_cast<double>((u - u0) * (u - u0) + (v - v0) * (v - v0));
      if (distance2 > max_distance2 || distance2 >= best_distance2) continue;
      if (row[u] == 0 || row[u] > max_depth_mm) continue;
      best_u = u;
      best_v = v;
      best_distance2 = distance2;
    }
  }
  if (best_u < 0) return std::nullopt;

  PixelLabelPoint result;
  result.depth_pixel = Eigen::Vector2i(best_u, best_v);
  result.depth_offset_px = std::sqrt(best_distance2);
  result.depth_m = depth.at<uint16_t>(best_v, best_u) / 1000.0;  // 16-bit millimetres
  store::LabelPoint& point = result.point;
  point.source = store::LabelPointSource::kKeyframePixel;
  point.keyframe = keyframe.id;
  point.pixel = pixel;
  point.cam_point = k.Unproject(pixel.x(), pixel.y(), result.depth_m);
  point.world = keyframe.world_from_cam * point.cam_point;
  return result;
}

store::LabelPoint LabelPointFromWorld(const Eigen::Vector3d& world) {
  SIGHTMAP_CHECK(world.allFinite(), "a label point needs three finite coordinates [m]");
  store::LabelPoint point;
  point.source = store::LabelPointSource::kTyped;
  point.world = world;
  return point;
}

store::LabelRecord AddPointsToLabel(store::Model& model, const std::string& name,
                                    const std::vector<store::LabelPoint>& points,
                                    const std::optional<std::string>& type) {
  // A usage error like every other bad name (exit 2), not a failure of the model.
  if (name.empty()) SIGHTMAP_THROW(InvalidArgument, "a label needs a name: pass --name NAME");
  SIGHTMAP_CHECK(!points.empty(), "label '" << name << "' needs at least one point");
  std::optional<store::LabelRecord> label = model.FindLabel(name);
  if (label) {
    label->points.insert(label->points.end(), points.begin(), points.end());
    if (type && !type->empty()) label->type = *type;
    model.UpdateLabel(*label);
  } else {
    label.emplace();
    label->name = name;
    label->type = TypeOrDefault(type);
    label->points = points;
    model.AddLabel(*label);
  }
  // Read back, so the caller sees the store's world coordinates and timestamps.
  std::optional<store::LabelRecord> stored = model.FindLabel(name);
  SIGHTMAP_CHECK(stored, "label '" << name << "' was written but cannot be read back");
  return *stored;
}

LabelImportReport ImportSceneLabels(store::Model& model, const std::string& path,
                                    const std::optional<ClickOptions>& as_clicked) {
  std::ifstream in = OpenInputFile(path, "scene file");
  SIGHTMAP_CHECK(in.is_open(), "cannot read scene file " << path << ": check that it exists");
  nlohmann::json scene;
  try {
    scene = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    // nlohmann's message ends with the position; keep the line to one sentence.
    std::string detail = e.what();
    for (char& c : detail) {
      if (c == '\n') c = ' ';
    }
    SIGHTMAP_THROW(Error, "scene file " << path << " is not valid JSON (" << detail
                                        << "): expected appliances.json from 'sightmap sim "
                                           "generate'");
  }
  SIGHTMAP_CHECK(
      scene.is_object() && scene.contains("appliances") && scene["appliances"].is_array(),
      "scene file " << path
                    << " has no \"appliances\" list: expected appliances.json from "
                       "'sightmap sim generate'");
  const nlohmann::json& appliances = scene["appliances"];
  SIGHTMAP_CHECK(!appliances.empty(), "scene file " << path << " lists no appliance");

  std::vector<store::LabelRecord> labels;
  std::vector<std::string> origins;
  for (size_t i = 0; i < appliances.size(); ++i) {
    const nlohmann::json& appliance = appliances[i];
    std::ostringstream where_stream;
    where_stream << "scene file " << path << ": appliance " << i + 1;
    const std::string where = where_stream.str();
    SIGHTMAP_CHECK(appliance.is_object() && appliance.contains("name") &&
                       appliance["name"].is_string() &&
                       !appliance["name"].get<std::string>().empty(),
                   where << " has no \"name\": fix the scene file");
    store::LabelRecord label;
    label.name = appliance["name"].get<std::string>();
    const std::string named = where + " ('" + label.name + "')";
    if (appliance.contains("type")) {
      SIGHTMAP_CHECK(appliance["type"].is_string(), named << ": \"type\" must be a string");
      label.type = appliance["type"].get<std::string>();
    }
    if (label.type.empty()) label.type = kDefaultLabelType;
    SIGHTMAP_CHECK(appliance.contains("points") && appliance["points"].is_array() &&
                       !appliance["points"].empty(),
                   named << " has no \"points\": give at least one [x, y, z]");
    const nlohmann::json& points = appliance["points"];
    for (size_t j = 0; j < points.size(); ++j) {
      store::LabelPoint point;
      point.source = store::LabelPointSource::kImportedFile;
      point.file = path;
      point.world = ParseScenePoint(points[j], named + " point " + std::to_string(j + 1));
      label.points.push_back(std::move(point));
    }
    labels.push_back(std::move(label));
    origins.push_back("appliance " + std::to_string(i + 1));
  }
  CheckUniqueNames(labels, origins);
  if (!as_clicked) return WriteLabels(model, std::move(labels), /*keep_existing_type=*/false);

  SIGHTMAP_CHECK_OPTIONS(*as_clicked);
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  int clicked_points = 0;
  std::vector<std::string> not_clicked;
  for (store::LabelRecord& label : labels) {
    bool all_clicked = true;
    for (store::LabelPoint& point : label.points) {
      const std::optional<PixelLabelPoint> clicked =
          ClickedLabelPoint(model, keyframes, point.world, *as_clicked);
      if (clicked) {
        point = clicked->point;
        ++clicked_points;
      } else {
        all_clicked = false;
      }
    }
    if (!all_clicked) not_clicked.push_back(label.name);
  }
  LabelImportReport report = WriteLabels(model, std::move(labels), /*keep_existing_type=*/false);
  report.clicked_points = clicked_points;
  std::sort(not_clicked.begin(), not_clicked.end());
  report.not_clicked = std::move(not_clicked);
  return report;
}

LabelImportReport ImportPointListLabels(store::Model& model, const std::vector<std::string>& paths,
                                        const std::optional<std::string>& type) {
  SIGHTMAP_CHECK(!paths.empty(), "no point-list file to import: pass one file per appliance");
  std::vector<store::LabelRecord> labels;
  for (const std::string& path : paths) {
    store::LabelRecord label;
    label.name = std::filesystem::path(path).stem().string();
    SIGHTMAP_CHECK(!label.name.empty(), "cannot name a label after " << path
                                                                     << ": its file name has no "
                                                                        "stem");
    label.type = TypeOrDefault(type);
    for (const Eigen::Vector3d& world : store::ReadPointList(path)) {  // throws naming a bad file
      store::LabelPoint point;
      point.source = store::LabelPointSource::kImportedFile;
      point.file = path;
      point.world = world;
      label.points.push_back(std::move(point));
    }
    labels.push_back(std::move(label));
  }
  CheckUniqueNames(labels, paths);
  const bool keep_existing_type = !type || type->empty();
  return WriteLabels(model, std::move(labels), keep_existing_type);
}

}  // namespace sightmap::identify

namespace sightmap::identify {

bool LabelViewOptions::Check(std::string* error) const {
  if (!(max_distance_m > 0.0) || !(depth_margin_m >= 0.0) || !(depth_margin_ratio >= 0.0)) {
    if (error) *error = "max_distance_m must be positive and the depth margins not negative";
    return false;
  }
  return true;
}

namespace {

// `world` in the keyframe's image: its pixel and depth, or nothing when it is behind the camera,
// outside the image or too far.
std::optional<std::pair<Eigen::Vector2d, double>> ProjectIntoKeyframe(
    const store::KeyframeInfo& keyframe, const Eigen::Vector3d& world, double max_distance_m) {
  const Eigen::Vector3d cam = keyframe.world_from_cam.inverse() * world;
  if (!(cam.z() > 0.0) || cam.norm() > max_distance_m) return std::nullopt;
  const Eigen::Vector2d pixel = keyframe.intrinsics.Project(cam);
  const Intrinsics& k = keyframe.intrinsics;
  // Pixel centres at integers: the image spans [-0.5, size - 0.5).
  if (!(pixel.x() >= -0.5 && pixel.x() < k.width - 0.5 && pixel.y() >= -0.5 &&
        pixel.y() < k.height - 0.5)) {
    return std::nullopt;
  }
  return std::make_pair(pixel, cam.z());
}

}  // namespace

Eigen::Vector3d LabelCentre(const store::LabelRecord& label) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const store::LabelPoint& point : label.points) sum += point.world;
  return label.points.empty() ? sum : Eigen::Vector3d(sum / label.points.size());
}

std::vector<LabelInKeyframe> LabelsInKeyframe(const store::Model& model, KeyframeId keyframe,
                                              const std::vector<store::LabelRecord>& labels,
                                              const LabelViewOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const store::KeyframeInfo info = model.Keyframe(keyframe);
  // The depth image is read only when a point falls in the image.
  for (const store::LabelRecord& label : labels) {
    for (const store::LabelPoint& point : label.points) {
      if (ProjectIntoKeyframe(info, point.world, options.max_distance_m)) {
        return LabelsInKeyframe(info, model.LoadDepth(keyframe), labels, options);
      }
    }
  }
  return {};
}

std::vector<LabelInKeyframe> LabelsInKeyframe(const store::KeyframeInfo& keyframe,
                                              const cv::Mat& depth_mm,
                                              const std::vector<store::LabelRecord>& labels,
                                              const LabelViewOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 && !depth_mm.empty(),
                 "a keyframe's depth must be 16-bit [mm]");
  // The depth image may be smaller than the keyframe's camera (a whole factor).
  const double scale_x = static_cast<double>(depth_mm.cols) / keyframe.intrinsics.width;
  const double scale_y = static_cast<double>(depth_mm.rows) / keyframe.intrinsics.height;
  std::vector<LabelInKeyframe> seen;
  for (const store::LabelRecord& label : labels) {
    LabelInKeyframe in_view{&label, {}};
    for (size_t p = 0; p < label.points.size(); ++p) {
      const auto projected =
          ProjectIntoKeyframe(keyframe, label.points[p].world, options.max_distance_m);
      if (!projected) continue;
      LabelPointInKeyframe point{p, projected->first, projected->second, false};
      const int u = std::clamp(static_cast<int>(std::lround(point.pixel.x() * scale_x)), 0,
                               depth_mm.cols - 1);
      const int v = std::clamp(static_cast<int>(std::lround(point.pixel.y() * scale_y)), 0,
                               depth_mm.rows - 1);
      const double surface_m = 1e-3 * depth_mm.at<uint16_t>(v, u);
      point.hidden = surface_m > 0.0 && surface_m < point.depth_m - options.depth_margin_m -
                                                        options.depth_margin_ratio * point.depth_m;
      in_view.points.push_back(point);
    }
    if (!in_view.points.empty()) seen.push_back(std::move(in_view));
  }
  return seen;
}

namespace {

// KeyframesSeeingLabel's keyframes themselves, in its order.
std::vector<const store::KeyframeInfo*> NearestKeyframesSeeing(
    const std::vector<store::KeyframeInfo>& keyframes, const store::LabelRecord& label,
    size_t max_count, const LabelViewOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::vector<std::pair<double, const store::KeyframeInfo*>> seeing;
  for (const store::KeyframeInfo& keyframe : keyframes) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const store::LabelPoint& point : label.points) {
      const auto projected = ProjectIntoKeyframe(keyframe, point.world, options.max_distance_m);
      if (projected) nearest = std::min(nearest, projected->second);
    }
    if (std::isfinite(nearest)) seeing.emplace_back(nearest, &keyframe);
  }
  std::stable_sort(seeing.begin(), seeing.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  if (seeing.size() > max_count) seeing.resize(max_count);
  std::vector<const store::KeyframeInfo*> nearest;
  for (const auto& [distance, keyframe] : seeing) nearest.push_back(keyframe);
  return nearest;
}

}  // namespace

std::vector<KeyframeId> KeyframesSeeingLabel(const std::vector<store::KeyframeInfo>& keyframes,
                                             const store::LabelRecord& label, size_t max_count,
                                             const LabelViewOptions& options) {
  std::vector<KeyframeId> ids;
  for (const store::KeyframeInfo* keyframe :
       NearestKeyframesSeeing(keyframes, label, max_count, options)) {
    ids.push_back(keyframe->id);
  }
  return ids;
}

bool ClickOptions::Check(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (max_keyframes < 1) return fail("max_keyframes must be at least 1");
  if (!(on_surface_m >= 0.0)) return fail("on_surface_m must not be negative");
  if (!(border_share >= 0.0 && border_share < 0.5)) return fail("border_share must be in [0, 0.5)");
  if (!(max_in_front_m >= 0.0) || !(max_behind_m >= 0.0)) {
    return fail("max_in_front_m and max_behind_m must not be negative");
  }
  if (!(sighting_depth_m >= 0.0) || !(sighting_max_m > 0.0)) {
    return fail("sighting_depth_m must not be negative and sighting_max_m must be positive");
  }
  return pixel.Check(error) && view.Check(error);
}

std::optional<PixelLabelPoint> ClickedLabelPoint(const store::Model& model,
                                                 const std::vector<store::KeyframeInfo>& keyframes,
                                                 const Eigen::Vector3d& world,
                                                 const ClickOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  store::LabelRecord probe;
  probe.points.push_back(LabelPointFromWorld(world));
  const std::vector<const store::KeyframeInfo*> seeing = NearestKeyframesSeeing(
      keyframes, probe, static_cast<size_t>(options.max_keyframes), options.view);
  struct Candidate {
    PixelLabelPoint clicked;
    Eigen::Vector3d ray;  // keyframe centre to the point, unit length (world)
    double gap_m = 0.0;   // how far the surface clicked lies in front of the point
  };
  std::vector<Candidate> candidates;
  // The side the walk saw the point from: the keyframes whose depth there is missing (a screen, a
  // window) or not nearer than the point by more than sighting_depth_m.
  Eigen::Vector3d front_ray = Eigen::Vector3d::Zero();
  for (const store::KeyframeInfo* info : seeing) {
    const KeyframeId id = info->id;
    const Intrinsics& k = info->intrinsics;
    const Eigen::Vector3d cam = info->world_from_cam.inverse() * world;
    const Eigen::Vector2d pixel = k.Project(cam);
    const double border_u = options.border_share * k.width;
    const double border_v = options.border_share * k.height;
    if (pixel.x() < border_u || pixel.x() > k.width - 1 - border_u || pixel.y() < border_v ||
        pixel.y() > k.height - 1 - border_v) {
      continue;
    }
    const cv::Mat depth = model.LoadDepth(id);
    CheckDepthFits(*info, depth);
    const Eigen::Vector3d ray = (world - info->world_from_cam.translation()).normalized();
    const uint16_t at_mm = depth.at<uint16_t>(static_cast<int>(std::lround(pixel.y())),
                                              static_cast<int>(std::lround(pixel.x())));
    if (ClearSighting(at_mm, cam.z(), options.sighting_depth_m, options.sighting_max_m)) {
      front_ray += ray;
    }
    const std::optional<PixelLabelPoint> clicked =
        LabelPointFromDepth(*info, depth, pixel, options.pixel);
    if (!clicked) continue;  // no depth there: a user would click in another keyframe
    const double gap_m = cam.z() - clicked->depth_m;
    if (gap_m > options.max_in_front_m || gap_m < -options.max_behind_m) continue;
    candidates.push_back({*clicked, ray, gap_m});
    if (std::abs(gap_m) <= options.on_surface_m) break;  // on the surface: seen from its side
  }
  // A keyframe behind the wall the point hangs on sees the wall's other face a wall's thickness
  // in front of it: when the walk saw the point from one side, clicks from the other are not
  // the appliance.
  std::optional<PixelLabelPoint> best;
  double best_gap_m = std::numeric_limits<double>::infinity();
  for (const Candidate& candidate : candidates) {
    if (candidate.ray.dot(front_ray) < 0.0) continue;
    if (std::abs(candidate.gap_m) < best_gap_m) {
      best_gap_m = std::abs(candidate.gap_m);
      best = candidate.clicked;
    }
  }
  return best;
}

}  // namespace sightmap::identify

namespace sightmap::identify {
namespace {

const char* SourceName(store::LabelPointSource source) {
  switch (source) {
    case store::LabelPointSource::kKeyframePixel:
      return "keyframe_pixel";
    case store::LabelPointSource::kImportedFile:
      return "imported_file";
    case store::LabelPointSource::kTyped:
      return "typed";
  }
  return "unknown";
}

}  // namespace

nlohmann::json LabelsToJson(const std::vector<store::LabelRecord>& labels) {
  nlohmann::json list = nlohmann::json::array();
  for (const store::LabelRecord& label : labels) {
    nlohmann::json points = nlohmann::json::array();
    nlohmann::json sources = nlohmann::json::array();
    for (const store::LabelPoint& point : label.points) {
      points.push_back({point.world.x(), point.world.y(), point.world.z()});
      nlohmann::json source = {{"source", SourceName(point.source)}};
      if (point.source == store::LabelPointSource::kKeyframePixel) {
        source["keyframe"] = point.keyframe.value();
        source["pixel"] = {point.pixel.x(), point.pixel.y()};
      }
      if (!point.file.empty()) source["file"] = point.file;
      sources.push_back(std::move(source));
    }
    list.push_back({{"id", label.id.value()},
                    {"name", label.name},
                    {"type", label.type},
                    {"points", std::move(points)},
                    {"point_sources", std::move(sources)}});
  }
  return {{"labels", std::move(list)}};
}

SIGHTMAP_OPTIONS_JSON(PixelLabelOptions, max_depth_search_px, max_depth_m)

SIGHTMAP_OPTIONS_JSON(LabelViewOptions, max_distance_m, depth_margin_m, depth_margin_ratio)

}  // namespace sightmap::identify
