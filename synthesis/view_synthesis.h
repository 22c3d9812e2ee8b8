// View synthesis: virtual keyframes rendered from the model at standpoints the walk missed, so a
// phone photo taken from there finds features that look as it does (the paper's Section 3.5).
//
// Why: local features (ORB, SIFT) match across some 40 degrees of viewpoint change. A person
// photographs an appliance from wherever they stand; a walk along a room sees most appliances from
// one side. Rendering the keyframes' textured depth from the missing side warps each surface as
// that viewpoint sees it, and its features then match the photo's.
//
// How: `coverage` finds each label's open sectors that no keyframe saw; a standpoint at eye
// height in each looks at the label. The keyframes that saw the label from the nearest directions
// are drawn one by one as textured meshes (their own depth, their own colour) through the OSMesa
// renderer, and composited nearest surface first, best source first. Features are extracted where
// the composite is whole, with 3D points from its depth, and stored as synthetic views: the
// Locator indexes and matches them like keyframes; mapping never reads them.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/features.h"
#include "identify/coverage.h"
#include "render/mesh_renderer.h"
#include "slam/features.h"
#include "store/model.h"

namespace sightmap::synthesis {

struct ViewSynthesisOptions {
  // Standpoints: in each open sector around a label (coverage), at each probed distance a person
  // could stand there and see it. With missing_sectors_only, only sectors no keyframe saw.
  bool missing_sectors_only = true;
  identify::CoverageOptions coverage;
  // A standpoint looking up or down more steeply than this at its label is skipped: nobody
  // photographs a ceiling light straight up, and the walk's keyframes hardly saw the ceiling [deg].
  double max_pitch_deg = 60.0;
  // Standpoints on a grid of free floor as well, not only around labels: every grid_step_m over
  // the coverage floor plan where a person fits (the cell crossed by the keyframes' depth, no
  // surface within grid_clearance_m at eye height), looking at each label whose distance lies in
  // the coverage distance band, in plain sight over the floor plan, and that no keyframe saw from
  // a similar view (ViewWasSeen with grid_seen: the walk's own view matches a photo taken there).
  // 0 turns the grid off [m], [m].
  double grid_step_m = 0.0;
  double grid_clearance_m = 0.3;
  identify::ViewSeenOptions grid_seen;

  // Sources: keyframes that saw the label (its centre inside the image, not hidden behind their
  // depth), the smallest angle between their line of sight to it and the standpoint's first, at
  // most max_sources of them, none more than max_source_angle_deg away [deg].
  int max_sources = 6;
  double max_source_angle_deg = 100.0;
  // A keyframe's depth is meshed every mesh_step_px pixels (the texture keeps its full resolution);
  // a quad whose corners' depths differ by more than max_edge_depth_ratio x their depth spans a
  // depth edge and is not drawn; depth beyond max_depth_m is too noisy to draw [px], [], [m].
  int mesh_step_px = 4;
  double max_edge_depth_ratio = 0.05;
  double max_depth_m = 6.0;
  // Compositing: per pixel the nearest surface of any source; the best-ranked source whose surface
  // lies within composite_depth_ratio x that depth of it gives the colour, so small registration
  // errors between sources do not stripe the image [].
  double composite_depth_ratio = 0.03;

  // A view is kept when at least min_drawn_share of its pixels are drawn and at least
  // min_features of its features lie wholly on drawn pixels with a 3D point.
  double min_drawn_share = 0.35;
  int min_features = 80;
  // Features as the mapper extracts them from keyframes (ORB, 1000).
  slam::FeatureOptions features;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const ViewSynthesisOptions& options);
void from_json(const nlohmann::json& json, ViewSynthesisOptions& options);

// Where to render a view, and for which label.
struct Standpoint {
  LabelId label;
  std::string label_name;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  // the label's centre [m]
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  double bearing_deg = 0.0;  // of the sector, around the label (coverage's convention)
  double distance_m = 0.0;
};
// One standpoint per open distance of each open (and, with missing_sectors_only, unseen) sector
// of each label.
std::vector<Standpoint> PlanStandpoints(const identify::ModelCoverage& coverage,
                                        const ViewSynthesisOptions& options);

// The grid standpoints (grid_step_m above; none when it is 0): at eye height on the floor plan's
// free cells, each looking at a label the keyframes (their poses) did not see from there.
std::vector<Standpoint> PlanGridStandpoints(const identify::ModelCoverage& coverage,
                                            const std::vector<store::KeyframeInfo>& keyframes,
                                            const ViewSynthesisOptions& options);

// A keyframe's depth [mm] as triangles in the world, textured with its colour image (texture
// handle `texture`), unlit so the colour is the keyframe's.
render::TriangleMesh KeyframeMesh(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                                  const Eigen::Isometry3d& world_from_cam, int texture,
                                  const ViewSynthesisOptions& options);

// Layers rendered from the same camera, best source first, composited: per pixel the nearest
// surface, coloured by the first layer within composite_depth_ratio of it.
struct Composite {
  cv::Mat color;    // CV_8UC3
  cv::Mat depth_m;  // CV_32F, 0 where nothing is drawn
  int drawn_pixels = 0;
};
Composite CompositeLayers(const std::vector<render::RenderedView>& layers, double depth_ratio);

// Keeps the features whose keypoint's patch (kp.size / 2 around it) lies wholly on drawn pixels
// (`drawn` CV_8U, non-zero where drawn): corners on the edge of a hole are the hole's, not the
// scene's.
Features KeepFeaturesOnDrawnPixels(const Features& features, const cv::Mat& drawn);

// Renders views from one model, which must outlive it. Not thread-safe (one off-screen context).
class ViewSynthesizer {
 public:
  // Reads the keyframes' poses; images are read per view. Throws Error when the model has none.
  ViewSynthesizer(const store::Model& model, const ViewSynthesisOptions& options);
  ~ViewSynthesizer();
  ViewSynthesizer(const ViewSynthesizer&) = delete;
  ViewSynthesizer& operator=(const ViewSynthesizer&) = delete;

  struct Result {
    std::optional<store::SyntheticViewRecord> view;  // nullopt when refused
    std::string refusal;                             // why not: "no keyframe saw the label", ...
    int sources = 0;
    double drawn_share = 0.0;
    int features = 0;  // kept, with a 3D point
  };
  // Renders a view at `world_from_cam` (the keyframes' intrinsics) of what the keyframes that saw
  // `target` show; `exclude` (optional) is never a source (tests render a keyframe's own view
  // from the others).
  Result Synthesize(const Eigen::Isometry3d& world_from_cam, const Eigen::Vector3d& target,
                    KeyframeId exclude = KeyframeId()) const;

  // The keyframes Synthesize would draw, best first.
  std::vector<KeyframeId> ChooseSources(const Eigen::Isometry3d& world_from_cam,
                                        const Eigen::Vector3d& target,
                                        KeyframeId exclude = KeyframeId()) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct SynthesisReport {
  int labels = 0;
  int standpoints = 0;
  int grid_standpoints = 0;  // of those, on the free-floor grid
  int written = 0;
  int refused = 0;
  int64_t deleted = 0;  // synthetic views the run replaced
  int64_t bytes = 0;    // stored by the views written
  double seconds = 0.0;
  std::vector<std::string> refusals;  // one line per refused standpoint
};
// {"labels", "standpoints", "grid_standpoints", "written", "refused", "deleted", "bytes",
// "seconds"}.
nlohmann::json ToJson(const SynthesisReport& report);

// Replaces the model's synthetic views with views rendered at the standpoints of its current
// coverage (PlanStandpoints, then PlanGridStandpoints). Each view is committed on its own and the
// previous views are removed only at the end, so a killed run leaves the previous views and those
// written so far (the next run replaces all). `progress` (optional) gets the standpoints done and
// their total. Throws Error when the model has no labels or no keyframes.
SynthesisReport SynthesizeViews(store::Model& model, const ViewSynthesisOptions& options,
                                const std::function<void(int, int)>& progress = nullptr);

}  // namespace sightmap::synthesis
