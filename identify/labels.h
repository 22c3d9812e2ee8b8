// Labelling appliances in a model (the modelling phase's last step, ARCHITECTURE.md): a pixel
// clicked on a keyframe becomes a 3D point through that keyframe's depth and pose; points are added
// to a label by name; whole sets of labels are imported from a simulator scene file
// (appliances.json) or from CloudCompare point lists. Label points are kept relative to their
// keyframe by the store, so they follow it when a loop closure moves the graph.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "store/model.h"

namespace sightmap::identify {

struct PixelLabelOptions {
  // When the clicked pixel has no depth, the depth of the nearest pixel (by pixel distance) that
  // has one is used, up to this far away [px]; 0 takes only the clicked pixel.
  double max_depth_search_px = 5.0;
  // Depths beyond this are not trusted (Kinect-class sensors: noise grows with the square of the
  // distance) and are treated as missing [m].
  double max_depth_m = 10.0;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const PixelLabelOptions& options);
void from_json(const nlohmann::json& json, PixelLabelOptions& options);

// A pixel turned into a label point, and where its depth came from.
struct PixelLabelPoint {
  store::LabelPoint point;       // kKeyframePixel: keyframe, pixel, cam_point, world
  Eigen::Vector2i depth_pixel;   // the pixel whose depth was used
  double depth_offset_px = 0.0;  // its distance from the clicked pixel [px]; 0 when it had depth
  double depth_m = 0.0;          // the depth used [m]
};

// Pixel (u, v) of `keyframe` (pixel centres at integer coordinates, as Intrinsics) to a point in
// its camera frame and in the world (its current optimised world_from_cam). The clicked pixel's
// ray is kept when a neighbour's depth is borrowed. Throws Error with one line when the keyframe is
// not in the model, the pixel is outside its image, or no depth lies within max_depth_search_px.
PixelLabelPoint LabelPointFromPixel(const store::Model& model, KeyframeId keyframe,
                                    const Eigen::Vector2d& pixel,
                                    const PixelLabelOptions& options = PixelLabelOptions());

// A point typed in world coordinates [m] (source kTyped).
store::LabelPoint LabelPointFromWorld(const Eigen::Vector3d& world);

// A label's points as one keyframe sees them, for drawing them on its image.
struct LabelPointInKeyframe {
  size_t point_index = 0;  // in LabelRecord::points
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  double depth_m = 0.0;  // along the keyframe's optical axis
  // The keyframe's own depth shows a surface in front of the point: it is behind something.
  bool hidden = false;
};
struct LabelInKeyframe {
  const store::LabelRecord* label = nullptr;  // into the labels given
  std::vector<LabelPointInKeyframe> points;
};

struct LabelViewOptions {
  double max_distance_m = 8.0;  // points further from the camera are not drawn [m]
  // A point is hidden when the keyframe's depth at its pixel is nearer by more than this plus
  // depth_margin_ratio x its depth (Kinect-class noise grows with depth) [m].
  double depth_margin_m = 0.10;
  double depth_margin_ratio = 0.05;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const LabelViewOptions& options);
void from_json(const nlohmann::json& json, LabelViewOptions& options);

// The mean of a label's points (the origin `coverage` counts directions from); zero for none.
Eigen::Vector3d LabelCentre(const store::LabelRecord& label);

// The labels with a point in `keyframe`'s image, in front of it and within max_distance_m, with
// those points' pixels; hidden ones marked through the keyframe's depth image (one read).
std::vector<LabelInKeyframe> LabelsInKeyframe(const store::Model& model, KeyframeId keyframe,
                                              const std::vector<store::LabelRecord>& labels,
                                              const LabelViewOptions& options = {});
// The same for a keyframe whose depth image [mm] the caller has read (it may be the keyframe's
// size divided by a whole factor).
std::vector<LabelInKeyframe> LabelsInKeyframe(const store::KeyframeInfo& keyframe,
                                              const cv::Mat& depth_mm,
                                              const std::vector<store::LabelRecord>& labels,
                                              const LabelViewOptions& options = {});

// Keyframes with one of `label`'s points in their image (in front, within max_distance_m; no
// occlusion test, no image read), nearest first, at most `max_count`.
std::vector<KeyframeId> KeyframesSeeingLabel(const std::vector<store::KeyframeInfo>& keyframes,
                                             const store::LabelRecord& label, size_t max_count,
                                             const LabelViewOptions& options = {});

// {"labels": [{"id", "name", "type", "points": [[x, y, z]], "point_sources": [{"source",
// "keyframe"?, "pixel"?, "file"?}]}]}: `sightmap label list --json` and the server's /api/labels.
nlohmann::json LabelsToJson(const std::vector<store::LabelRecord>& labels);

// The type a label gets when none is given.
inline constexpr const char* kDefaultLabelType = "appliance";

// Appends `points` to the label `name`, creating it when absent with `type` (kDefaultLabelType when
// nullopt or empty). An existing label keeps its type unless `type` names a new one. Returns the
// label as stored. Throws Error on an empty name or no point.
store::LabelRecord AddPointsToLabel(store::Model& model, const std::string& name,
                                    const std::vector<store::LabelPoint>& points,
                                    const std::optional<std::string>& type = std::nullopt);

// What an import did, by label name (sorted).
struct LabelImportReport {
  std::vector<std::string> created;
  std::vector<std::string> replaced;  // existing labels whose points (and type) were replaced
  int points = 0;                     // points written in total
};

// Labels every appliance of a simulator scene file ({"scene", "appliances": [{"id", "name",
// "type", "points": [[x, y, z], ...]}]}, as `sightmap sim generate` writes it): one label per
// appliance, named after it, of its type, with its points (kImportedFile, file = path). The file's
// coordinates are taken as model world coordinates. A label of the same name is replaced (points
// and type), since the scene file is the ground truth. Everything is validated before the first
// write, so a bad file (unreadable, not JSON, a missing field, a point that is not three finite
// numbers, a name twice) throws Error and leaves the model unchanged; should a write fail midway,
// the labels already written are restored.
LabelImportReport ImportSceneLabels(store::Model& model, const std::string& path);

// CloudCompare point lists (store/label_files.h's ReadPointList), one label per file named after
// its stem. New labels get `type` (kDefaultLabelType when nullopt or empty); an existing label's
// points are replaced, and its type too when `type` is given. All or nothing, as ImportSceneLabels;
// two files with the same stem are an Error.
LabelImportReport ImportPointListLabels(store::Model& model, const std::vector<std::string>& paths,
                                        const std::optional<std::string>& type = std::nullopt);

}  // namespace sightmap::identify
