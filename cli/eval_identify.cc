#include "cli/eval_identify.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli/command_util.h"
#include "core/atomic_file.h"
#include "core/check.h"
#include "core/format.h"
#include "core/timing.h"
#include "identify/coverage.h"
#include "identify/identify_eval.h"
#include "identify/locator.h"
#include "render/image_file.h"
#include "slam/matching.h"
#include "store/model.h"

namespace sightmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

std::string Share(int part, int whole) {
  std::ostringstream text;
  text << std::setw(5) << part << " / " << std::left << std::setw(5) << whole << std::right << " "
       << std::setw(6) << (whole > 0 ? Fixed(100.0 * part / whole, 1) : std::string("-")) << "%";
  return text.str();
}

// A status line on stderr every 2 s (rewritten in place on a terminal), so a 200-photo run that
// takes a minute shows it is alive.
class Progress {
 public:
  explicit Progress(size_t total) : total_(total), tty_(::isatty(2) != 0) {}
  void Update(size_t done, int matched, bool last) {
    const double elapsed = SecondsSince(start_);
    if (!last && elapsed - last_print_s_ < 2.0) return;
    last_print_s_ = elapsed;
    const double per_photo = done > 0 ? elapsed / static_cast<double>(done) : 0.0;
    std::cerr << (tty_ ? "\r" : "") << "eval identify: " << done << "/" << total_ << " photos, "
              << matched << " matched, " << Fixed(per_photo * 1e3, 0) << " ms/photo";
    if (!last) {
      std::cerr << ", about " << Fixed(per_photo * static_cast<double>(total_ - done), 0)
                << " s left";
    }
    std::cerr << (tty_ && !last ? "   " : "\n") << std::flush;
  }

 private:
  size_t total_;
  bool tty_;
  Clock::time_point start_ = Clock::now();
  double last_print_s_ = -1e9;
};

void PrintTable(const EvalIdentifyArgs& args, size_t keyframes,
                const identify::IdentifyEvaluation& e) {
  std::cout << "model      " << args.model_path << " (" << keyframes << " keyframes)\n";
  std::cout << "queries    " << args.queries_path << " (" << e.photos << " photos)\n";
  if (args.seeing_keyframes_first) {
    std::cout << "retrieval  the keyframes that saw each view first (--seeing-keyframes-first)\n";
  }
  std::cout << "\n";
  const int recall_undefined = e.matched_photos - e.recall_defined_photos;
  const int precision_undefined = e.matched_photos - e.precision_defined_photos;
  const std::string good = Fixed(e.options.good_share, 1);
  std::cout << "photos matched                 " << Share(e.matched_photos, e.photos) << "\n";
  std::cout << "recall >= " << good << " (matched)       "
            << Share(e.recall_good_photos, e.recall_defined_photos) << "   " << recall_undefined
            << " with no visible appliance left out\n";
  std::cout << "precision >= " << good << " (matched)    "
            << Share(e.precision_good_photos, e.precision_defined_photos) << "   "
            << precision_undefined << " with nothing identified left out\n";
  std::cout << "wrong poses (> " << Fixed(e.options.wrong_position_m, 1) << " m or > "
            << Fixed(e.options.wrong_rotation_deg, 0) << " deg)  "
            << Share(e.wrong_poses, e.matched_photos) << "   median error "
            << Fixed(100.0 * e.median_position_error_m, 1) << " cm, "
            << Fixed(e.median_rotation_error_deg, 2) << " deg (" << e.posed_photos
            << " with a true pose)\n";
  if (e.ambiguous_photos > 0) {
    std::cout << "ambiguous, right place named   "
              << Share(e.ambiguous_right_place_photos, e.ambiguous_photos)
              << "   (of the photos answered with two possible places)\n";
  }
  std::cout << "occluded reported as visible   "
            << Share(e.occluded_identified, e.occluded_instances) << "\n";
  const int not_visible = e.categories[0][0] + e.categories[0][1];
  std::cout << "not visible reported visible   " << Share(e.not_visible_identified, not_visible)
            << "\n";
  if (e.unknown_identified > 0) {
    std::cout << "names not in the ground truth  " << e.unknown_identified << "\n";
  }
  if (e.retrieval_photos > 0) {
    std::cout << "a keyframe that saw the view retrieved within rank";
    for (size_t k = 0; k < e.options.retrieval_ranks.size(); ++k) {
      std::cout << (k == 0 ? " " : ", ") << e.options.retrieval_ranks[k] << ": "
                << Share(e.retrieval_found[k], e.retrieval_photos);
    }
    std::cout << "\n";
  }
  std::cout << "\ninstances of matched photos (partially visible: either answer is right)\n";
  std::cout << std::left << std::setw(20) << "ground truth" << std::right << std::setw(12)
            << "identified" << std::setw(16) << "not identified"
            << "\n";
  for (int type = identify::kNumTruthTypes - 1; type >= 0; --type) {
    const auto& row = e.categories[static_cast<size_t>(type)];
    std::cout << std::left << std::setw(20) << ToString(static_cast<identify::TruthType>(type))
              << std::right << std::setw(12) << row[1] << std::setw(16) << row[0] << "\n";
  }
  std::cout << "\ntimings [ms]   median      p95     mean      max   (matching kernel: "
            << slam::KernelName(slam::FastestKernel()) << ")\n";
  for (const char* stage : {"features", "retrieval", "matching", "pnp", "visibility", "total"}) {
    const auto found = e.stages.find(stage);
    if (found == e.stages.end()) continue;
    const identify::StageTiming& t = found->second;
    std::cout << std::left << std::setw(12) << stage << std::right << std::setw(9)
              << Fixed(t.median_ms, 1) << std::setw(9) << Fixed(t.p95_ms, 1) << std::setw(9)
              << Fixed(t.mean_ms, 1) << std::setw(9) << Fixed(t.max_ms, 1) << "\n";
  }
  if (!e.unmatched_reasons.empty()) {
    std::vector<std::pair<int, std::string>> reasons;
    for (const auto& [reason, count] : e.unmatched_reasons) reasons.emplace_back(count, reason);
    std::sort(reasons.rbegin(), reasons.rend());
    std::cout << "\nnot matched, by reason\n";
    for (size_t i = 0; i < std::min<size_t>(reasons.size(), 5); ++i) {
      std::cout << std::setw(6) << reasons[i].first << "  " << reasons[i].second << "\n";
    }
  }
  if (!args.plot_path.empty()) std::cout << "\nplot       " << args.plot_path << "\n";
}

// Marks each photo whose view the model saw (identify::ViewWasSeen of the photo's target label),
// where the photo has a true pose and the model a label of its target's name: seen by a keyframe,
// or by a synthetic view when the locator matches against them.
void MarkCoveredPhotos(const store::Model& model, bool with_synthetic_views,
                       std::vector<identify::QueryTruth>* truths) {
  std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  if (with_synthetic_views) {
    for (const store::SyntheticViewRecord& view : model.SyntheticViews()) {
      store::KeyframeInfo info;
      info.world_from_cam = view.world_from_cam;
      info.intrinsics = view.intrinsics;
      keyframes.push_back(info);
    }
  }
  std::map<std::string, Eigen::Vector3d> label_points;
  for (const store::LabelRecord& label : model.Labels()) {
    label_points[label.name] = label.points.front().world;
  }
  for (identify::QueryTruth& truth : *truths) {
    const auto label = label_points.find(truth.target);
    if (!truth.world_from_cam || label == label_points.end()) continue;
    const identify::ViewSeenOptions seen;
    truth.view_angle_deg = identify::NearestViewAngleDeg(*truth.world_from_cam, label->second,
                                                         keyframes, seen.max_distance_ratio);
    truth.covered = identify::IsSeenAngle(truth.view_angle_deg, seen);
    truth.seeing_keyframes.clear();
    for (const size_t i :
         identify::KeyframesSeeingView(*truth.world_from_cam, label->second, keyframes, seen)) {
      // Synthetic views have no id of their own here: retrieval ranks the model's keyframes.
      if (keyframes[i].id.valid()) truth.seeing_keyframes.push_back(keyframes[i].id.value());
    }
  }
}

// The headline figures of the photos whose `covered` is `covered`, or nullopt when none is.
std::optional<identify::IdentifyEvaluation> EvaluateStratum(
    const std::vector<identify::QueryTruth>& truths,
    const std::vector<identify::PhotoAnswer>& answers, bool covered) {
  std::vector<identify::QueryTruth> selected_truths;
  std::vector<identify::PhotoAnswer> selected_answers;
  identify::SelectCovered(truths, answers, covered, &selected_truths, &selected_answers);
  if (selected_truths.empty()) return std::nullopt;
  return identify::EvaluateIdentification(selected_truths, selected_answers);
}

void PrintStrata(const std::optional<identify::IdentifyEvaluation>& covered,
                 const std::optional<identify::IdentifyEvaluation>& not_covered) {
  if (!covered && !not_covered) return;
  std::cout
      << "\nby coverage (a keyframe or synthetic view saw the photo's target within 40 deg and "
         "a factor 2 in distance)\n";
  std::cout << std::left << std::setw(14) << "" << std::right << std::setw(8) << "photos"
            << std::setw(10) << "matched" << std::setw(8) << "wrong" << std::setw(12)
            << "recall>=.8" << std::setw(14) << "precision>=.8"
            << "\n";
  for (const auto& [name, e] :
       {std::make_pair("covered", covered), std::make_pair("not covered", not_covered)}) {
    if (!e) continue;
    std::cout << std::left << std::setw(14) << name << std::right << std::setw(8) << e->photos
              << std::setw(9) << Fixed(100.0 * e->matched_ratio, 1) << "%" << std::setw(8)
              << e->wrong_poses << std::setw(11) << Fixed(100.0 * e->recall_ge_0_8_ratio, 1) << "%"
              << std::setw(13) << Fixed(100.0 * e->precision_ge_0_8_ratio, 1) << "%\n";
  }
}

}  // namespace

CLI::App* AddEvalIdentify(CLI::App& eval, EvalIdentifyArgs& args) {
  CLI::App* identify = eval.add_subcommand(
      "identify",
      "locate every phone photo of a simulator query set and report the paper's Section 5 "
      "figures: matched share, the 8-category table, recall/precision >= 0.8, occluded false "
      "positives, per-stage timings");
  identify->add_option("--model", args.model_path, "the labelled model")->required();
  identify
      ->add_option("--queries", args.queries_path,
                   "the folder 'sightmap sim generate --queries N --out DIR' wrote (DIR or "
                   "DIR/queries, holding queries.json)")
      ->required();
  identify->add_flag("--json", args.json, "print one JSON object (stable keys) instead of text");
  identify->add_option("--plot", args.plot_path,
                       "write the category table and recall/precision histograms (PNG)");
  identify->add_option("--plot-size", args.plot_size, "plot size WxH [px]")->capture_default_str();
  identify->add_option("--limit", args.limit, "locate only the first N photos (0: all)")
      ->check(Within(0, 1e9))
      ->capture_default_str();
  AddConfigOption(*identify, args.locator,
                  "read the locator's options from this JSON file (as 'sightmap locate "
                  "--print-config' prints them), to measure a setting");
  identify->add_flag("--without-synthetic", args.without_synthetic_views,
                     "ignore the model's synthetic views ('sightmap synthesize'), to see what they "
                     "add");
  identify->add_flag("--seeing-keyframes-first", args.seeing_keyframes_first,
                     "search the keyframes that saw each photo's view (known from its true pose) "
                     "before those retrieval ranks: what matching and the checks answer when "
                     "retrieval is perfect");
  identify->add_option("--photos-out", args.photos_out,
                       "write one JSON line per photo: its answer, inliers, keyframe and pose "
                       "error, to find the photos behind a figure");
  return identify;
}

int RunEvalIdentify(const EvalIdentifyArgs& args) {
  int plot_width = 0;
  int plot_height = 0;
  if (!args.plot_path.empty()) {
    const ImageSize size = ParseImageSize(args.plot_size, "--plot-size", {600, 360}, 8000);
    plot_width = size.width;
    plot_height = size.height;
    CheckOutputFile(args.plot_path, "--plot");
  }
  if (!args.photos_out.empty()) CheckOutputFile(args.photos_out, "--photos-out");
  std::vector<identify::QueryTruth> truths = identify::ReadQueryTruths(args.queries_path);
  SIGHTMAP_CHECK(!truths.empty(), "the query set " << args.queries_path << " holds no photo");
  if (args.limit > 0 && static_cast<size_t>(args.limit) < truths.size()) {
    truths.resize(static_cast<size_t>(args.limit));
  }

  std::cerr << "eval identify: loading " << args.model_path << "\n" << std::flush;
  const Clock::time_point load_start = Clock::now();
  store::ModelOptions model_options;
  model_options.read_only = true;
  std::unique_ptr<identify::Locator> locator;
  {
    const store::Model model = store::Model::Open(args.model_path, model_options);
    identify::LocatorOptions locator_options = args.locator;
    if (args.without_synthetic_views) locator_options.use_synthetic_views = false;
    locator = std::make_unique<identify::Locator>(
        model, locator_options, TenthsProgress("eval identify: loaded", "keyframes"));
    if (!locator->LoadWarning().empty()) {
      std::cerr << "sightmap: " << locator->LoadWarning() << "\n";
    }
    MarkCoveredPhotos(model, locator_options.use_synthetic_views, &truths);
  }
  const double load_s = SecondsSince(load_start);

  std::vector<identify::PhotoAnswer> answers;
  answers.reserve(truths.size());
  Progress progress(truths.size());
  int matched = 0;
  for (const identify::QueryTruth& truth : truths) {
    identify::Photo photo;
    try {
      photo = identify::ReadPhotoFile(truth.image_path, identify::kMaxPhotoMegapixels);
    } catch (const InvalidArgument& e) {
      SIGHTMAP_THROW(InvalidArgument,
                     e.what() << " (listed in queries.json; was the query set copied whole?)");
    }
    // queries.json gives the intrinsics at the written size; a resized copy keeps the camera.
    identify::IntrinsicsHint hint;
    hint.upright = truth.intrinsics;
    const Clock::time_point start = Clock::now();
    std::vector<KeyframeId> first_keyframes;
    if (args.seeing_keyframes_first) {
      for (const int64_t id : truth.seeing_keyframes) first_keyframes.emplace_back(id);
    }
    const identify::LocateResult result = locator->Locate(photo, hint, first_keyframes);
    const double wall_ms = SecondsSince(start) * 1e3;
    identify::PhotoAnswer answer = identify::ToPhotoAnswer(result);
    if (answer.timings.total_ms <= 0.0) answer.timings.total_ms = wall_ms;
    matched += answer.matched ? 1 : 0;
    answers.push_back(std::move(answer));
    progress.Update(answers.size(), matched, answers.size() == truths.size());
  }

  const identify::IdentifyEvaluation evaluation = identify::EvaluateIdentification(truths, answers);
  const std::optional<identify::IdentifyEvaluation> covered =
      EvaluateStratum(truths, answers, true);
  const std::optional<identify::IdentifyEvaluation> not_covered =
      EvaluateStratum(truths, answers, false);
  if (!args.plot_path.empty()) {
    render::WriteImageAtomically(args.plot_path,
                                 identify::DrawIdentifyPlot(evaluation, plot_width, plot_height));
  }
  if (!args.photos_out.empty()) {
    std::string lines;
    for (const nlohmann::json& row : identify::PhotoRows(truths, answers)) {
      lines += row.dump() + "\n";
    }
    WriteFileAtomically(args.photos_out, lines);
  }
  if (args.json) {
    nlohmann::json out = identify::ToJson(evaluation);
    out["model"] = args.model_path;
    out["queries"] = args.queries_path;
    out["keyframes"] = locator->NumKeyframes();
    out["model_load_s"] = load_s;
    out["match_kernel"] = slam::KernelName(slam::FastestKernel());
    out["seeing_keyframes_first"] = args.seeing_keyframes_first;
    out["plot"] = args.plot_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.plot_path);
    out["covered"] = covered ? identify::ToJson(*covered) : nlohmann::json(nullptr);
    out["not_covered"] = not_covered ? identify::ToJson(*not_covered) : nlohmann::json(nullptr);
    std::cout << out.dump(2) << "\n";
    return kExitSuccess;
  }
  PrintTable(args, locator->NumKeyframes(), evaluation);
  PrintStrata(covered, not_covered);
  return kExitSuccess;
}

}  // namespace sightmap::cli
