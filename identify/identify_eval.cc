#include "identify/identify_eval.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"

namespace sightmap::identify {
namespace {

namespace fs = std::filesystem;

constexpr const char* kTruthNames[kNumTruthTypes] = {"not_visible", "occluded", "partially_visible",
                                                     "visible"};

// A share in [0, 1] to its histogram bin: `bins` equal bins over [0, 1), then one for exactly 1.
int BinOf(double share, int bins) {
  if (share >= 1.0) return bins;
  // The epsilon keeps 0.3 (3 of 10) in bin 3 although 0.3 * 10 may round below 3.
  return std::clamp(static_cast<int>(std::floor(share * bins + 1e-9)), 0, bins - 1);
}

double Ratio(int numerator, int denominator) {
  return denominator > 0 ? static_cast<double>(numerator) / denominator : 0.0;
}

StageTiming Summarise(const std::vector<double>& values) {
  StageTiming timing;
  if (values.empty()) return timing;
  timing.median_ms = Percentile(values, 0.5);
  timing.p95_ms = Percentile(values, 0.95);
  double sum = 0.0;
  for (double v : values) sum += v;
  timing.mean_ms = sum / static_cast<double>(values.size());
  timing.max_ms = *std::max_element(values.begin(), values.end());
  return timing;
}

Intrinsics ReadIntrinsics(const nlohmann::json& k) {
  Intrinsics intrinsics;
  // Not get<int>(): nlohmann casts an out-of-range number unchecked.
  options_json::ReadNumber(k.at("width"), intrinsics.width);
  options_json::ReadNumber(k.at("height"), intrinsics.height);
  intrinsics.fx = k.at("fx").get<double>();
  intrinsics.fy = k.at("fy").get<double>();
  intrinsics.cx = k.at("cx").get<double>();
  intrinsics.cy = k.at("cy").get<double>();
  return intrinsics;
}

}  // namespace

const char* ToString(TruthType type) { return kTruthNames[static_cast<int>(type)]; }

TruthType ParseTruthType(const std::string& text) {
  for (int i = 0; i < kNumTruthTypes; ++i) {
    if (text == kTruthNames[i]) return static_cast<TruthType>(i);
  }
  SIGHTMAP_THROW(Error, "unknown ground-truth type '"
                            << text
                            << "' (expected not_visible, occluded, partially_visible or visible)");
}

std::vector<QueryTruth> ReadQueryTruths(const std::string& path) {
  fs::path file = path;
  if (fs::is_directory(file)) {
    if (fs::is_regular_file(file / "queries" / "queries.json")) {
      file = file / "queries" / "queries.json";
    } else {
      file = file / "queries.json";
    }
  }
  SIGHTMAP_CHECK(fs::is_regular_file(file),
                 "no queries.json in " << path
                                       << ": pass the folder written by 'sightmap sim generate "
                                          "--queries N --out DIR' (DIR or DIR/queries)");
  std::ifstream in(file);
  SIGHTMAP_CHECK(in.good(), "cannot read " << file.string());
  nlohmann::json root;
  try {
    in >> root;
  } catch (const nlohmann::json::exception& e) {
    SIGHTMAP_THROW(Error, file.string() << " is not valid JSON: " << e.what());
  }
  // Image paths are relative to the dataset folder ("queries/0001.jpg"); the file sits in
  // DIR/queries/, so its parent's parent is the dataset.
  const fs::path queries_dir = file.parent_path();
  const fs::path dataset_dir = queries_dir.parent_path();
  std::vector<QueryTruth> truths;
  try {
    for (const nlohmann::json& query : root.at("queries")) {
      QueryTruth truth;
      const fs::path image = query.at("image").get<std::string>();
      const fs::path candidates[] = {dataset_dir / image, queries_dir / image.filename()};
      truth.image_path = candidates[0].string();
      for (const fs::path& candidate : candidates) {
        if (fs::is_regular_file(candidate)) {
          truth.image_path = candidate.string();
          break;
        }
      }
      if (query.contains("intrinsics")) truth.intrinsics = ReadIntrinsics(query["intrinsics"]);
      for (const auto& [name, type] : query.at("types").items()) {
        truth.appliances[name] = ParseTruthType(type.get<std::string>());
      }
      truth.target = query.value("target", "");
      if (query.contains("world_from_cam")) {
        const nlohmann::json& pose = query["world_from_cam"];
        const std::vector<double> p = pose.at("position").get<std::vector<double>>();
        const std::vector<double> q = pose.at("quaternion_xyzw").get<std::vector<double>>();
        SIGHTMAP_CHECK(p.size() == 3 && q.size() == 4,
                       file.string() << ": a query's world_from_cam needs 3 position and 4 "
                                        "quaternion values");
        Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
        world_from_cam.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().matrix();
        world_from_cam.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
        truth.world_from_cam = world_from_cam;
      }
      truths.push_back(std::move(truth));
    }
  } catch (const nlohmann::json::exception& e) {
    SIGHTMAP_THROW(Error, file.string()
                              << " does not look like a simulator query set: " << e.what());
  } catch (const OptionsJsonError& e) {
    SIGHTMAP_THROW(Error, file.string() << ": a query's intrinsics width or height " << e.reason());
  }
  return truths;
}

PhotoAnswer ToPhotoAnswer(const LocateResult& result) {
  PhotoAnswer answer;
  answer.matched = result.matched;
  answer.reason = result.reason;
  answer.timings = result.timings;
  answer.photo_detail_cells = result.photo_detail_cells;
  answer.second_look = result.second_look;
  for (const KeyframeId& id : result.retrieved_keyframes) {
    answer.retrieved.push_back(id.valid() ? id.value() : -1);
  }
  if (!result.matched) {
    answer.refused_world_from_cam = result.refused_world_from_cam;
    answer.refused_inliers = result.refused_inliers;
    for (const PossiblePlace& place : result.possible_places) {
      answer.possible_places.push_back(place.world_from_cam);
    }
    return answer;
  }
  answer.matches = result.matches;
  answer.runner_up_inliers = result.runner_up_inliers;
  answer.projected_points = result.projected_points;
  answer.inlier_cells = result.inlier_cells;
  answer.view_agreement = result.view_agreement;
  answer.world_from_cam = result.world_from_cam;
  answer.inliers = result.inliers;
  if (result.keyframe.valid()) answer.keyframe = result.keyframe.value();
  for (const ApplianceInView& appliance : result.appliances) {
    (appliance.occluded ? answer.reported_occluded : answer.identified).push_back(appliance.name);
  }
  return answer;
}

bool IdentifyEvalOptions::Check(std::string* error) const {
  if (!(good_share > 0.0 && good_share <= 1.0)) {
    if (error != nullptr) *error = "good_share must be in (0, 1]";
    return false;
  }
  if (histogram_bins < 1 || histogram_bins > 100) {
    if (error != nullptr) *error = "histogram_bins must be in [1, 100]";
    return false;
  }
  if (!(wrong_position_m > 0.0 && wrong_rotation_deg > 0.0)) {
    if (error != nullptr) *error = "wrong_position_m and wrong_rotation_deg must be positive";
    return false;
  }
  if (std::any_of(retrieval_ranks.begin(), retrieval_ranks.end(), [](int r) { return r < 1; })) {
    if (error != nullptr) *error = "retrieval_ranks must be 1 or more";
    return false;
  }
  return true;
}

PoseError ComparePoses(const Eigen::Isometry3d& truth, const Eigen::Isometry3d& estimate) {
  PoseError error;
  error.position_m = (truth.translation() - estimate.translation()).norm();
  error.rotation_deg = RotationAngleDeg(truth.linear(), estimate.linear());
  return error;
}

bool IsWrongPose(const PoseError& error, const IdentifyEvalOptions& options) {
  return error.position_m > options.wrong_position_m ||
         error.rotation_deg > options.wrong_rotation_deg;
}

std::optional<int> RetrievalRank(const std::vector<int64_t>& retrieved,
                                 const std::vector<int64_t>& seeing) {
  const std::set<int64_t> seen(seeing.begin(), seeing.end());
  for (size_t i = 0; i < retrieved.size(); ++i) {
    if (retrieved[i] >= 0 && seen.count(retrieved[i]) > 0) return static_cast<int>(i) + 1;
  }
  return std::nullopt;
}

void SelectCovered(const std::vector<QueryTruth>& truths, const std::vector<PhotoAnswer>& answers,
                   bool covered, std::vector<QueryTruth>* selected_truths,
                   std::vector<PhotoAnswer>* selected_answers) {
  SIGHTMAP_CHECK(truths.size() == answers.size(), "SelectCovered: truths and answers differ");
  selected_truths->clear();
  selected_answers->clear();
  for (size_t i = 0; i < truths.size(); ++i) {
    if (truths[i].covered != covered) continue;
    selected_truths->push_back(truths[i]);
    selected_answers->push_back(answers[i]);
  }
}

std::vector<nlohmann::json> PhotoRows(const std::vector<QueryTruth>& truths,
                                      const std::vector<PhotoAnswer>& answers,
                                      const IdentifyEvalOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(truths.size() == answers.size(), "PhotoRows: " << truths.size()
                                                                << " ground truths but "
                                                                << answers.size() << " answers");
  std::vector<nlohmann::json> rows;
  rows.reserve(truths.size());
  for (size_t i = 0; i < truths.size(); ++i) {
    const QueryTruth& truth = truths[i];
    const PhotoAnswer& answer = answers[i];
    nlohmann::json row;
    row["index"] = i;
    row["image"] = truth.image_path;
    row["target"] = truth.target;
    row["covered"] = truth.covered ? nlohmann::json(*truth.covered) : nlohmann::json();
    row["view_angle_deg"] =
        truth.view_angle_deg ? nlohmann::json(*truth.view_angle_deg) : nlohmann::json();
    row["matched"] = answer.matched;
    row["reason"] = answer.matched ? nlohmann::json() : nlohmann::json(answer.reason);
    row["inliers"] = answer.matched ? nlohmann::json(answer.inliers) : nlohmann::json();
    row["keyframe"] = answer.keyframe ? nlohmann::json(*answer.keyframe) : nlohmann::json();
    row["world_from_cam"] = nlohmann::json();
    if (answer.matched && answer.world_from_cam) {
      const Eigen::Vector3d t = answer.world_from_cam->translation();
      const Eigen::Quaterniond q(answer.world_from_cam->linear());
      row["world_from_cam"] = {{"position", {t.x(), t.y(), t.z()}},
                               {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
    }
    row["position_error_m"] = nlohmann::json();
    row["rotation_error_deg"] = nlohmann::json();
    row["wrong_pose"] = nlohmann::json();
    if (answer.matched && answer.world_from_cam && truth.world_from_cam) {
      const PoseError error = ComparePoses(*truth.world_from_cam, *answer.world_from_cam);
      row["position_error_m"] = error.position_m;
      row["rotation_error_deg"] = error.rotation_deg;
      row["wrong_pose"] = IsWrongPose(error, options);
    }
    // A refused pose's error tells a right refusal (a wrong pose kept out) from a lost answer.
    row["refused_inliers"] = nlohmann::json();
    row["refused_position_error_m"] = nlohmann::json();
    row["refused_rotation_error_deg"] = nlohmann::json();
    if (!answer.matched && answer.refused_world_from_cam) {
      row["refused_inliers"] = answer.refused_inliers;
      if (truth.world_from_cam) {
        const PoseError error = ComparePoses(*truth.world_from_cam, *answer.refused_world_from_cam);
        row["refused_position_error_m"] = error.position_m;
        row["refused_rotation_error_deg"] = error.rotation_deg;
      }
    }
    row["possible_place_position_errors_m"] = nlohmann::json::array();
    for (const Eigen::Isometry3d& place : answer.possible_places) {
      if (!truth.world_from_cam) break;
      row["possible_place_position_errors_m"].push_back(
          ComparePoses(*truth.world_from_cam, place).position_m);
    }
    row["seeing_keyframes"] = truth.seeing_keyframes.size();
    const std::optional<int> rank = RetrievalRank(answer.retrieved, truth.seeing_keyframes);
    row["retrieval_rank"] = rank ? nlohmann::json(*rank) : nlohmann::json();
    row["identified"] = answer.identified;
    const auto if_matched = [&](int value) {
      return answer.matched ? nlohmann::json(value) : nlohmann::json();
    };
    row["matches"] = if_matched(answer.matches);
    row["runner_up_inliers"] = if_matched(answer.runner_up_inliers);
    row["projected_points"] = if_matched(answer.projected_points);
    row["inlier_cells"] = if_matched(answer.inlier_cells);
    row["view_agreement"] =
        answer.view_agreement ? nlohmann::json(*answer.view_agreement) : nlohmann::json();
    row["photo_detail_cells"] = answer.photo_detail_cells;
    row["second_look"] = answer.second_look;
    const LocateTimings& t = answer.timings;
    row["timings_ms"] = {{"features", t.features_ms},      {"retrieval", t.retrieval_ms},
                         {"matching", t.matching_ms},      {"pnp", t.pnp_ms},
                         {"visibility", t.visibility_ms},  {"total", t.total_ms},
                         {"second_look", t.second_look_ms}};
    rows.push_back(std::move(row));
  }
  return rows;
}

IdentifyEvaluation EvaluateIdentification(const std::vector<QueryTruth>& truths,
                                          const std::vector<PhotoAnswer>& answers,
                                          const IdentifyEvalOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(truths.size() == answers.size(),
                 "EvaluateIdentification: " << truths.size() << " ground truths but "
                                            << answers.size() << " answers");
  IdentifyEvaluation out;
  out.options = options;
  out.photos = static_cast<int>(truths.size());
  out.recall_histogram.assign(static_cast<size_t>(options.histogram_bins + 1), 0);
  out.precision_histogram.assign(static_cast<size_t>(options.histogram_bins + 1), 0);
  out.retrieval_found.assign(options.retrieval_ranks.size(), 0);
  std::map<std::string, std::vector<double>> stage_values;
  std::vector<double> position_errors;
  std::vector<double> rotation_errors;
  for (size_t i = 0; i < truths.size(); ++i) {
    const QueryTruth& truth = truths[i];
    const PhotoAnswer& answer = answers[i];
    const LocateTimings& t = answer.timings;
    stage_values["features"].push_back(t.features_ms);
    stage_values["retrieval"].push_back(t.retrieval_ms);
    stage_values["matching"].push_back(t.matching_ms);
    stage_values["pnp"].push_back(t.pnp_ms);
    stage_values["visibility"].push_back(t.visibility_ms);
    stage_values["total"].push_back(t.total_ms);
    out.second_look_photos += answer.second_look ? 1 : 0;
    if (!truth.seeing_keyframes.empty()) {
      ++out.retrieval_photos;
      const std::optional<int> rank = RetrievalRank(answer.retrieved, truth.seeing_keyframes);
      for (size_t k = 0; k < options.retrieval_ranks.size(); ++k) {
        out.retrieval_found[k] += rank && *rank <= options.retrieval_ranks[k] ? 1 : 0;
      }
    }
    if (!answer.matched) {
      ++out.unmatched_reasons[answer.reason.empty() ? "(no reason given)" : answer.reason];
      if (!answer.possible_places.empty()) {
        ++out.ambiguous_photos;
        out.ambiguous_right_place_photos +=
            truth.world_from_cam &&
            std::any_of(answer.possible_places.begin(), answer.possible_places.end(),
                        [&](const Eigen::Isometry3d& place) {
                          return !IsWrongPose(ComparePoses(*truth.world_from_cam, place), options);
                        });
      }
      continue;
    }
    ++out.matched_photos;
    if (truth.world_from_cam && answer.world_from_cam) {
      const PoseError error = ComparePoses(*truth.world_from_cam, *answer.world_from_cam);
      ++out.posed_photos;
      out.wrong_poses += IsWrongPose(error, options);
      position_errors.push_back(error.position_m);
      rotation_errors.push_back(error.rotation_deg);
    }
    // A name reported twice is one identification.
    const std::set<std::string> identified(answer.identified.begin(), answer.identified.end());
    int visible = 0;
    int visible_found = 0;
    int correct = 0;  // identified and visible or partially visible
    for (const auto& [name, type] : truth.appliances) {
      const bool found = identified.count(name) > 0;
      ++out.categories[static_cast<size_t>(type)][found ? 1 : 0];
      if (type == TruthType::kVisible) {
        ++visible;
        visible_found += found ? 1 : 0;
      }
      if (found && (type == TruthType::kVisible || type == TruthType::kPartiallyVisible)) {
        ++correct;
      }
      if (type == TruthType::kOccluded) {
        ++out.occluded_instances;
        out.occluded_identified += found ? 1 : 0;
      }
      if (type == TruthType::kNotVisible && found) ++out.not_visible_identified;
    }
    for (const std::string& name : identified) {
      if (truth.appliances.count(name) == 0) ++out.unknown_identified;
    }
    std::optional<double> recall;
    std::optional<double> precision;
    if (visible > 0) recall = Ratio(visible_found, visible);
    if (!identified.empty()) precision = Ratio(correct, static_cast<int>(identified.size()));
    const auto tally = [&](const std::optional<double>& share, int* defined, int* good,
                           std::vector<int>* histogram) {
      if (!share) return;
      ++*defined;
      if (*share >= options.good_share - 1e-12) ++*good;
      ++(*histogram)[static_cast<size_t>(BinOf(*share, options.histogram_bins))];
    };
    tally(recall, &out.recall_defined_photos, &out.recall_good_photos, &out.recall_histogram);
    tally(precision, &out.precision_defined_photos, &out.precision_good_photos,
          &out.precision_histogram);
    out.recall.push_back(recall);
    out.precision.push_back(precision);
  }
  out.matched_ratio = Ratio(out.matched_photos, out.photos);
  out.recall_ge_0_8_ratio = Ratio(out.recall_good_photos, out.recall_defined_photos);
  out.precision_ge_0_8_ratio = Ratio(out.precision_good_photos, out.precision_defined_photos);
  out.occluded_false_positive_ratio = Ratio(out.occluded_identified, out.occluded_instances);
  out.wrong_pose_ratio = Ratio(out.wrong_poses, out.matched_photos);
  if (!position_errors.empty()) {
    out.median_position_error_m = Percentile(position_errors, 0.5);
    out.median_rotation_error_deg = Percentile(rotation_errors, 0.5);
  }
  for (const auto& [stage, values] : stage_values) out.stages[stage] = Summarise(values);
  return out;
}

nlohmann::json ToJson(const IdentifyEvaluation& e) {
  nlohmann::json out;
  out["photos"] = e.photos;
  out["matched_photos"] = e.matched_photos;
  out["matched_ratio"] = e.matched_ratio;
  out["recall_ge_0_8_ratio"] = e.recall_ge_0_8_ratio;
  out["precision_ge_0_8_ratio"] = e.precision_ge_0_8_ratio;
  out["recall_defined_photos"] = e.recall_defined_photos;
  out["recall_undefined_photos"] = e.matched_photos - e.recall_defined_photos;
  out["precision_defined_photos"] = e.precision_defined_photos;
  out["precision_undefined_photos"] = e.matched_photos - e.precision_defined_photos;
  out["good_share"] = e.options.good_share;
  out["occluded_instances"] = e.occluded_instances;
  out["occluded_identified"] = e.occluded_identified;
  out["occluded_false_positive_ratio"] = e.occluded_false_positive_ratio;
  out["not_visible_identified"] = e.not_visible_identified;
  out["posed_photos"] = e.posed_photos;
  out["second_look_photos"] = e.second_look_photos;
  out["wrong_poses"] = e.wrong_poses;
  out["ambiguous_photos"] = e.ambiguous_photos;
  out["ambiguous_right_place_photos"] = e.ambiguous_right_place_photos;
  out["wrong_pose_ratio"] = e.wrong_pose_ratio;
  out["median_position_error_m"] = e.median_position_error_m;
  out["median_rotation_error_deg"] = e.median_rotation_error_deg;
  out["unknown_identified"] = e.unknown_identified;
  out["retrieval_photos"] = e.retrieval_photos;
  nlohmann::json recall = nlohmann::json::object();
  for (size_t k = 0; k < e.options.retrieval_ranks.size() && k < e.retrieval_found.size(); ++k) {
    recall[std::to_string(e.options.retrieval_ranks[k])] =
        Ratio(e.retrieval_found[k], e.retrieval_photos);
  }
  out["retrieval_recall"] = recall;
  nlohmann::json categories = nlohmann::json::object();
  for (int type = 0; type < kNumTruthTypes; ++type) {
    categories[kTruthNames[type]] = {
        {"identified", e.categories[static_cast<size_t>(type)][1]},
        {"not_identified", e.categories[static_cast<size_t>(type)][0]}};
  }
  out["categories"] = categories;
  out["recall_histogram"] = e.recall_histogram;
  out["precision_histogram"] = e.precision_histogram;
  out["histogram_bins"] = "equal bins over [0, 1), the last one for exactly 1.0";
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [stage, timing] : e.stages) {
    stages[stage] = {{"median", timing.median_ms},
                     {"p95", timing.p95_ms},
                     {"mean", timing.mean_ms},
                     {"max", timing.max_ms}};
    out[stage + "_median_ms"] = timing.median_ms;
    out[stage + "_p95_ms"] = timing.p95_ms;
  }
  out["stages_ms"] = stages;
  const auto total = e.stages.find("total");
  out["locate_median_ms"] = total != e.stages.end() ? total->second.median_ms : 0.0;
  out["locate_p95_ms"] = total != e.stages.end() ? total->second.p95_ms : 0.0;
  nlohmann::json reasons = nlohmann::json::object();
  for (const auto& [reason, count] : e.unmatched_reasons) reasons[reason] = count;
  out["unmatched_reasons"] = reasons;
  return out;
}

namespace {

const cv::Scalar kRight(80, 170, 60);     // BGR green: the outcome is right
const cv::Scalar kWrong(60, 60, 210);     // red: an error
const cv::Scalar kEither(170, 170, 170);  // grey: either outcome is fine
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kLight(225, 225, 225);  // light grey: empty bars and plot frames

std::string Percent(double share) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(1) << 100.0 * share << "%";
  return text.str();
}

void Text(cv::Mat& image, const std::string& text, cv::Point at, double scale = 0.5,
          const cv::Scalar& colour = kInk, int thickness = 1) {
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

// Horizontal 100% bars, one per ground-truth type, split into identified / not identified.
void DrawCategories(cv::Mat& image, const IdentifyEvaluation& e, cv::Rect area) {
  Text(image, "Instances of matched photos by ground truth", {area.x, area.y + 16}, 0.6, kInk, 2);
  // Which outcome is right for each type: identified (visible), not identified (not visible,
  // occluded), either (partially visible).
  const cv::Scalar identified_colour[kNumTruthTypes] = {kWrong, kWrong, kEither, kRight};
  const cv::Scalar missed_colour[kNumTruthTypes] = {kRight, kRight, kEither, kWrong};
  const int label_w = 150;
  const int bar_x = area.x + label_w;
  const int bar_w = area.width - label_w - 10;
  const int row_h = (area.height - 80) / kNumTruthTypes;
  for (int type = kNumTruthTypes - 1, row = 0; type >= 0; --type, ++row) {
    const int y = area.y + 36 + row * row_h;
    const int h = row_h - 22;
    const int yes = e.categories[static_cast<size_t>(type)][1];
    const int no = e.categories[static_cast<size_t>(type)][0];
    const int all = yes + no;
    Text(image, kTruthNames[type], {area.x, y + h / 2 + 5});
    cv::rectangle(image, cv::Rect(bar_x, y, bar_w, h), kLight, cv::FILLED);
    if (all > 0) {
      const int yes_w = static_cast<int>(std::lround(bar_w * Ratio(yes, all)));
      if (yes_w > 0) {
        cv::rectangle(image, cv::Rect(bar_x, y, yes_w, h), identified_colour[type], cv::FILLED);
      }
      if (bar_w - yes_w > 0) {
        cv::rectangle(image, cv::Rect(bar_x + yes_w, y, bar_w - yes_w, h), missed_colour[type],
                      cv::FILLED);
      }
    }
    std::ostringstream note;
    note << "identified " << yes << " (" << Percent(Ratio(yes, all)) << ")   not identified " << no
         << " (" << Percent(Ratio(no, all)) << ")";
    Text(image, note.str(), {bar_x + 6, y + h + 15}, 0.45);
  }
  const int legend_y = area.y + area.height - 22;
  const std::pair<cv::Scalar, const char*> legend[] = {
      {kRight, "right"}, {kWrong, "error"}, {kEither, "either is fine"}};
  int x = bar_x;
  for (const auto& [colour, text] : legend) {
    cv::rectangle(image, cv::Rect(x, legend_y - 11, 14, 14), colour, cv::FILLED);
    Text(image, text, {x + 20, legend_y});
    x += 150;
  }
}

void DrawHistogram(cv::Mat& image, const std::string& title, const std::vector<int>& histogram,
                   int defined, int undefined, double good_ratio, double good_share,
                   cv::Rect area) {
  Text(image, title, {area.x, area.y + 16}, 0.6, kInk, 2);
  std::ostringstream summary;
  summary << ">= " << good_share << ": " << Percent(good_ratio) << " of " << defined << " photos ("
          << undefined << " undefined)";
  Text(image, summary.str(), {area.x, area.y + 38}, 0.45);
  const int bins = static_cast<int>(histogram.size());
  const int plot_x = area.x + 40;
  const int plot_y = area.y + 50;
  const int plot_w = area.width - 50;
  const int plot_h = area.height - 90;
  const int peak = std::max(1, *std::max_element(histogram.begin(), histogram.end()));
  cv::rectangle(image, cv::Rect(plot_x, plot_y, plot_w, plot_h), kLight, 1);
  const int bar_w = plot_w / std::max(1, bins);
  const int regular = bins - 1;  // the last bin is exactly 1.0
  for (int b = 0; b < bins; ++b) {
    const int count = histogram[static_cast<size_t>(b)];
    const int h = static_cast<int>(std::lround(static_cast<double>(plot_h) * count / peak));
    const double lower = static_cast<double>(b) / std::max(1, regular);
    const bool good = b == regular || lower >= good_share - 1e-9;
    const cv::Rect bar(plot_x + b * bar_w + 2, plot_y + plot_h - h, bar_w - 4, h);
    if (h > 0) cv::rectangle(image, bar, good ? kRight : kWrong, cv::FILLED);
    if (count > 0) Text(image, std::to_string(count), {bar.x + 2, bar.y - 4}, 0.4);
  }
  // Ticks at the regular bins' lower edges; the last bar is labelled "=1" instead.
  for (int b = 0; b < regular; b += std::max(1, regular / 5)) {
    std::ostringstream tick;
    tick << std::setprecision(2) << static_cast<double>(b) / std::max(1, regular);
    Text(image, tick.str(), {plot_x + b * bar_w - 8, plot_y + plot_h + 16}, 0.4);
  }
  Text(image, "=1", {plot_x + regular * bar_w + bar_w / 2 - 8, plot_y + plot_h + 16}, 0.4);
  Text(image, std::to_string(peak), {area.x, plot_y + 10}, 0.4);
  Text(image, "0", {area.x + 20, plot_y + plot_h}, 0.4);
}

}  // namespace

cv::Mat DrawIdentifyPlot(const IdentifyEvaluation& e, int width_px, int height_px) {
  SIGHTMAP_CHECK(width_px >= 600 && height_px >= 360,
                 "the identification plot needs at least 600x360 pixels, got " << width_px << "x"
                                                                               << height_px);
  cv::Mat image(height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  std::ostringstream header;
  header << e.photos << " photos, " << e.matched_photos << " matched (" << Percent(e.matched_ratio)
         << ");  occluded reported as visible: " << e.occluded_identified << " of "
         << e.occluded_instances << " (" << Percent(e.occluded_false_positive_ratio) << ")";
  const auto total = e.stages.find("total");
  if (total != e.stages.end()) {
    header << ";  locate median " << std::fixed << std::setprecision(0) << total->second.median_ms
           << " ms, p95 " << total->second.p95_ms << " ms";
  }
  Text(image, header.str(), {16, 26}, 0.55, kInk, 1);
  const int top = 44;
  const int left_w = width_px / 2;
  DrawCategories(image, e, cv::Rect(16, top, left_w - 24, height_px - top - 10));
  const int right_x = left_w + 10;
  const int right_w = width_px - right_x - 16;
  const int half_h = (height_px - top - 10) / 2;
  const int undefined_recall = e.matched_photos - e.recall_defined_photos;
  const int undefined_precision = e.matched_photos - e.precision_defined_photos;
  DrawHistogram(image, "Per-photo recall (matched photos)", e.recall_histogram,
                e.recall_defined_photos, undefined_recall, e.recall_ge_0_8_ratio,
                e.options.good_share, cv::Rect(right_x, top, right_w, half_h));
  DrawHistogram(image, "Per-photo precision (matched photos)", e.precision_histogram,
                e.precision_defined_photos, undefined_precision, e.precision_ge_0_8_ratio,
                e.options.good_share, cv::Rect(right_x, top + half_h, right_w, half_h));
  return image;
}

}  // namespace sightmap::identify
