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

// The same for a keyframe whose depth image [mm, its intrinsics' size] the caller has read;
// nullopt when the pixel is outside it or no depth lies within max_depth_search_px.
std::optional<PixelLabelPoint> LabelPointFromDepth(const store::KeyframeInfo& keyframe,
                                                   const cv::Mat& depth,
                                                   const Eigen::Vector2d& pixel,
                                                   const PixelLabelOptions& options);

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

// Where a user labelling an appliance in the model would click: the options of
// ClickedLabelPoint.
struct ClickOptions {
  // Keyframes tried, nearest to the point first (KeyframesSeeingLabel with `view`): the nearest
  // may all stand on the other side of the wall the appliance hangs on, so many are tried.
  int max_keyframes = 400;
  // A keyframe whose depth lies this close to the point shows it on its surface: taken at once
  // [m].
  double on_surface_m = 0.03;
  // A keyframe is clicked in only where the point lies this share of its width and height away
  // from the image border (a user clicks what the image shows whole) [].
  double border_share = 0.1;
  // The keyframe's depth at the point's pixel must show a surface at most this far in front of
  // the point (a scene's point may be its appliance's centre: a printer's lies 0.24 m behind its
  // front), else something else hides it there, and at most max_behind_m behind it [m].
  double max_in_front_m = 0.4;
  double max_behind_m = 0.1;
  // The side the walk saw the point from (a wall-mounted point seen from behind its wall must not
  // be clicked there): keyframes whose depth at the point is missing, with the point within
  // sighting_max_m, or not nearer than it by more than sighting_depth_m (ClearSighting, as the
  // sightings `locate` tells occlusion with); clicks in keyframes looking from the other side
  // (rays more than 90 deg from their mean) are dropped [m].
  double sighting_depth_m = 0.10;
  double sighting_max_m = 4.5;
  PixelLabelOptions pixel;
  LabelViewOptions view;

  bool Check(std::string* error) const;
};

// The label point a user would make by clicking `world` in a keyframe that shows it
// (LabelPointFromPixel at its pixel): of the keyframes passing ClickOptions, the one whose depth
// there lies nearest the point (the first within on_surface_m, else the first of the nearest);
// on the surface that keyframe's depth shows, stored relative to it, and never from the side
// opposite the one the walk saw the point from. nullopt when no keyframe passes. A point no
// keyframe saw clearly (a printer's centre, inside its body) has no side: the nearest surface
// wins, which for a wall-mounted point the walk saw only from behind would be the wall's other
// face, so the walk must show the appliance.
std::optional<PixelLabelPoint> ClickedLabelPoint(const store::Model& model,
                                                 const std::vector<store::KeyframeInfo>& keyframes,
                                                 const Eigen::Vector3d& world,
                                                 const ClickOptions& options = {});

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
  // As clicked (ImportSceneLabels with ClickOptions): points placed on a keyframe's surface, and
  // the labels with a point no keyframe showed (kept where the file puts it).
  int clicked_points = 0;
  std::vector<std::string> not_clicked;
};

// Labels every appliance of a simulator scene file ({"scene", "appliances": [{"id", "name",
// "type", "points": [[x, y, z], ...]}]}, as `sightmap sim generate` writes it): one label per
// appliance, named after it, of its type, with its points (kImportedFile, file = path). The file's
// coordinates are taken as model world coordinates. A label of the same name is replaced (points
// and type), since the scene file is the ground truth. Everything is validated before the first
// write, so a bad file (unreadable, not JSON, a missing field, a point that is not three finite
// numbers, a name twice) throws Error and leaves the model unchanged; should a write fail midway,
// the labels already written are restored.
// With `as_clicked`, each point is replaced by ClickedLabelPoint's, as a user labelling in the
// model would place it (a scene's points may lie inside their appliance, where no surface is);
// a point no keyframe shows keeps the file's position.
LabelImportReport ImportSceneLabels(store::Model& model, const std::string& path,
                                    const std::optional<ClickOptions>& as_clicked = std::nullopt);

// CloudCompare point lists (store/label_files.h's ReadPointList), one label per file named after
// its stem. New labels get `type` (kDefaultLabelType when nullopt or empty); an existing label's
// points are replaced, and its type too when `type` is given. All or nothing, as ImportSceneLabels;
// two files with the same stem are an Error.
LabelImportReport ImportPointListLabels(store::Model& model, const std::vector<std::string>& paths,
                                        const std::optional<std::string>& type = std::nullopt);

}  // namespace sightmap::identify
