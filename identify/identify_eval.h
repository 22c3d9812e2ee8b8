// The identification metrics of the paper's Section 5 (ARCHITECTURE.md, "Measuring it"): how many
// phone photos were matched, the 8-category table of appliance instances (ground-truth type x
// identified or not), per-photo recall and precision with their histograms, false positives on
// occluded instances, and per-stage timings. `sightmap eval identify` feeds it the simulator's
// queries.json and the Locator's answers.
//
// Definitions (the paper's Figure 6 treats a partially visible appliance as optional):
// - An instance is (photo, appliance) over the appliances of the photo's ground truth; the table
//   counts the instances of matched photos only (an unmatched photo identifies nothing, and is
//   counted by matched_ratio instead).
// - Identified = reported by the Locator as in view and not occluded.
// - Per-photo recall = identified visible / visible. A partially visible appliance is not in the
//   denominator: missing it is not a miss.
// - Per-photo precision = identified visible-or-partially-visible / identified. Identifying a
//   partially visible appliance is not an error; identifying a not-visible or occluded one (or a
//   name the ground truth does not know) is.
// - A photo with no visible appliance has no recall, and one with nothing identified has no
//   precision: such photos are left out of that share (the counts are reported beside it).
// - recall_ge_0_8_ratio = matched photos with recall >= 0.8 / matched photos that have a recall;
//   precision_ge_0_8_ratio likewise.
// - occluded_false_positive_ratio = occluded instances identified / occluded instances (of
//   matched photos).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/statistics.h"  // Percentile, used with the evaluation
#include "identify/locator.h"

namespace sightmap::identify {

// The simulator's ground-truth classes (sim/simulator.h VisibilityType), in table order.
enum class TruthType { kNotVisible = 0, kOccluded = 1, kPartiallyVisible = 2, kVisible = 3 };
constexpr int kNumTruthTypes = 4;
const char* ToString(TruthType type);  // "not_visible", "occluded", ...
// Parses the queries.json spelling; throws Error on an unknown one.
TruthType ParseTruthType(const std::string& text);

// One phone photo and its ground truth, as queries.json holds them.
struct QueryTruth {
  std::string image_path;                           // resolved, readable path of the photo
  std::optional<Intrinsics> intrinsics;             // as given by the dataset
  std::map<std::string, TruthType> appliances;      // appliance name -> type
  std::string target;                               // the appliance the photo was taken of
  std::optional<Eigen::Isometry3d> world_from_cam;  // the phone's true pose
  // Whether the model saw this view (ViewWasSeen), set by the caller; nullopt = not known.
  std::optional<bool> covered;
  // The nearest view's angle to the photo's line of sight to its target (NearestViewAngleDeg),
  // set by the caller; nullopt = not known or no view within the distance factor [deg].
  std::optional<double> view_angle_deg;
  // The ids of the keyframes that saw the view (KeyframesSeeingView), set by the caller; empty
  // when not known or none did.
  std::vector<int64_t> seeing_keyframes;
};

// Reads a simulator query set. `path` may be the dataset folder (holding queries/queries.json),
// the queries/ folder itself, or the queries.json file. Throws Error naming what is missing.
std::vector<QueryTruth> ReadQueryTruths(const std::string& path);

// What the system answered for one photo.
struct PhotoAnswer {
  bool matched = false;
  std::string reason;                               // why not, when not matched
  std::vector<std::string> identified;              // names reported in view and not occluded
  std::vector<std::string> reported_occluded;       // names reported in the view cone but occluded
  std::optional<Eigen::Isometry3d> world_from_cam;  // the pose found, when matched
  int inliers = 0;                                  // of the pose, when matched
  std::optional<int64_t> keyframe;  // the keyframe holding most of its inliers, when matched
  LocateTimings timings;
  // What the locator's checks saw (LocateResult's), to tell right poses from wrong ones.
  int matches = 0;
  int runner_up_inliers = 0;
  int projected_points = 0;
  int inlier_cells = 0;
  int photo_detail_cells = 0;
  bool second_look = false;              // LocateResult's
  std::optional<double> view_agreement;  // LocateResult's
  // When not matched: the pose the answer would have been, and its inliers (LocateResult's).
  std::optional<Eigen::Isometry3d> refused_world_from_cam;
  int refused_inliers = 0;
  // When ambiguous: the poses of the places it named (LocateResult::possible_places).
  std::vector<Eigen::Isometry3d> possible_places;
  // LocateResult::retrieved_keyframes: ids best first, -1 for a synthetic view.
  std::vector<int64_t> retrieved;
};
PhotoAnswer ToPhotoAnswer(const LocateResult& result);

struct IdentifyEvalOptions {
  double good_share = 0.8;  // the paper's threshold for "recall / precision >= 0.8"
  int histogram_bins = 10;  // equal bins over [0, 1) plus one bin for exactly 1.0
  // A matched photo's pose is wrong beyond either (the "> 0.5 m or > 10 deg").
  double wrong_position_m = 0.5;
  double wrong_rotation_deg = 10.0;
  // Retrieval recall is counted at these ranks (the locator's defaults try 20 candidates, then 40
  // more in reserve).
  std::vector<int> retrieval_ranks = {1, 5, 20, 60};

  bool Check(std::string* error) const;
};

struct StageTiming {
  double median_ms = 0.0;
  double p95_ms = 0.0;
  double mean_ms = 0.0;
  double max_ms = 0.0;
};

struct IdentifyEvaluation {
  int photos = 0;
  int matched_photos = 0;
  int second_look_photos = 0;  // that the RootSIFT search ran on (matched or not)
  double matched_ratio = 0.0;
  // categories[type][identified ? 1 : 0]: instances of matched photos.
  std::array<std::array<int, 2>, kNumTruthTypes> categories{};
  int unknown_identified = 0;  // identified names that the photo's ground truth does not list
  // Per matched photo; nullopt where undefined (see the definitions above).
  std::vector<std::optional<double>> recall;
  std::vector<std::optional<double>> precision;
  int recall_defined_photos = 0;
  int precision_defined_photos = 0;
  int recall_good_photos = 0;  // recall >= good_share
  int precision_good_photos = 0;
  double recall_ge_0_8_ratio = 0.0;
  double precision_ge_0_8_ratio = 0.0;
  // histogram_bins bins over [0, 1) then one for exactly 1.0; counts of matched photos.
  std::vector<int> recall_histogram;
  std::vector<int> precision_histogram;
  int occluded_instances = 0;
  int occluded_identified = 0;
  double occluded_false_positive_ratio = 0.0;
  int not_visible_identified = 0;  // the other kind of false positive
  // Matched photos with a true pose, those posed wrongly (wrong_position_m / wrong_rotation_deg),
  // wrong / matched, and the median errors of the posed ones.
  int posed_photos = 0;
  int wrong_poses = 0;
  // Unmatched photos answered with possible places (ambiguous), and those of them with a true
  // pose one of whose places is right (not a wrong pose by the thresholds above).
  int ambiguous_photos = 0;
  int ambiguous_right_place_photos = 0;
  double wrong_pose_ratio = 0.0;
  double median_position_error_m = 0.0;
  double median_rotation_error_deg = 0.0;
  // Per stage over every located photo (matched or not).
  std::map<std::string, StageTiming>
      stages;  // features, retrieval, matching, pnp, visibility, total
  std::map<std::string, int> unmatched_reasons;  // reason -> photos
  // Photos some keyframe saw (QueryTruth::seeing_keyframes not empty), and per
  // options.retrieval_ranks entry those whose first seeing keyframe retrieval ranked within it.
  int retrieval_photos = 0;
  std::vector<int> retrieval_found;
  IdentifyEvalOptions options;
};

// Distance between the camera centres [m] and angle of the relative rotation [deg].
struct PoseError {
  double position_m = 0.0;
  double rotation_deg = 0.0;
};
PoseError ComparePoses(const Eigen::Isometry3d& truth, const Eigen::Isometry3d& estimate);
// Beyond options.wrong_position_m or options.wrong_rotation_deg.
bool IsWrongPose(const PoseError& error, const IdentifyEvalOptions& options);
// The 1-based rank of the first of `retrieved` that is one of `seeing`; nullopt when none is.
std::optional<int> RetrievalRank(const std::vector<int64_t>& retrieved,
                                 const std::vector<int64_t>& seeing);

// `truths` and `answers` are parallel (photo i).
IdentifyEvaluation EvaluateIdentification(const std::vector<QueryTruth>& truths,
                                          const std::vector<PhotoAnswer>& answers,
                                          const IdentifyEvalOptions& options = {});

// The photos (truths and answers, parallel) whose `covered` is `covered`.
void SelectCovered(const std::vector<QueryTruth>& truths, const std::vector<PhotoAnswer>& answers,
                   bool covered, std::vector<QueryTruth>* selected_truths,
                   std::vector<PhotoAnswer>* selected_answers);

// One JSON object per photo (truths and answers parallel), to find the photos behind a figure:
// "index", "image", "target", "covered" (null when unknown), "view_angle_deg" (QueryTruth's, null
// when unknown), "matched", "reason" (null when matched), "inliers" and "keyframe" (null when not
// matched), "position_error_m", "rotation_error_deg" and "wrong_pose" (null unless matched with a
// true pose, wrong as EvaluateIdentification counts it), "identified" (names in view and not
// occluded), and the checks' figures: "matches", "runner_up_inliers", "projected_points",
// "inlier_cells" (null when not matched) and "photo_detail_cells"; for a photo not matched,
// "refused_inliers", "refused_position_error_m" and "refused_rotation_error_deg" of the pose the
// answer would have been (null when there was none, the errors also without a true pose), and
// "possible_place_position_errors_m" of an ambiguous answer's places (empty for others or
// without a true pose); "seeing_keyframes" (how many saw the view) and "retrieval_rank"
// (RetrievalRank, null when none was retrieved or none saw it).
std::vector<nlohmann::json> PhotoRows(const std::vector<QueryTruth>& truths,
                                      const std::vector<PhotoAnswer>& answers,
                                      const IdentifyEvalOptions& options = {});

// Stable keys: photos, matched_photos, matched_ratio, recall_ge_0_8_ratio, precision_ge_0_8_ratio,
// posed_photos, wrong_poses, wrong_pose_ratio, median_position_error_m, median_rotation_error_deg,
// ambiguous_photos, ambiguous_right_place_photos, occluded_false_positive_ratio,
// retrieval_photos, retrieval_recall ({"<rank>": share of retrieval_photos}), locate_median_ms,
// locate_p95_ms, categories
// ({"visible": {"identified", "not_identified"}, ...}), recall/precision histograms and counts,
// stages_ms ({"features": {"median", "p95", "mean", "max"}, ...}) and <stage>_median_ms /
// <stage>_p95_ms.
nlohmann::json ToJson(const IdentifyEvaluation& evaluation);

// The paper's Figures 6 and 7 made clearer, as one BGR image: each ground-truth type's instances
// as a bar split into identified / not identified (green where that is right, red where it is an
// error, grey where either is fine), and the recall and precision histograms of matched photos.
cv::Mat DrawIdentifyPlot(const IdentifyEvaluation& evaluation, int width_px = 1200,
                         int height_px = 560);

}  // namespace sightmap::identify
