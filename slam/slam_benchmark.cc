// SLAM on the synthetic building at 1 Hz: throughput, latency per stage, peak memory, and the
// accuracy figures of the SLAM issue (ATE against ground truth, every accepted loop checked
// against ground truth, a deliberately false loop).
//
// Frames are rendered before mapping starts, so the figures are the mapper's alone.
//   slam_benchmark --trajectory handheld --frames 600
//   slam_benchmark --trajectory robot --frames 600 --false-loop
//   slam_benchmark --frames 150 --overlap   (what consecutive 1 Hz frames share, by ground truth)
//   slam_benchmark --frames 1500 --fps 5 --overlap   (the same walk at 5 Hz, every frame mapped)
//   slam_benchmark --frames 600 --laps 4   (the same 600 frames four times: cost against map size)
//   slam_benchmark --frames 600 --manhattan   (the building's axes fitted to each depth image)

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/peak_memory.h"
#include "core/rotation.h"
#include "core/statistics.h"
#include "core/timing.h"
#include "core/tum_format.h"
#include "sim/simulator.h"
#include "slam/features.h"
#include "slam/manhattan_frame.h"
#include "slam/mapper.h"
#include "slam/registration.h"
#include "slam/tracker.h"
#include "slam/trajectory_eval.h"

namespace sightmap::slam {
namespace {

struct Frame {
  TimestampNs timestamp_ns = 0;
  cv::Mat color;
  cv::Mat depth;
  Eigen::Isometry3d world_from_cam_gt;
};

double Median(const std::vector<double>& values) { return Percentile(values, 0.5); }

struct RunResult {
  TrajectoryError error;
  bool false_loop_injected = false;
  int keyframes = 0;
  int loops = 0;
  int loops_rejected = 0;
  int false_loops = 0;
  int segments = 0;
  int manhattan_keyframes = 0;  // keyframes with a rotation prior from the building's axes
  // The largest joined part of the map and its ATE aligned on its own: how good the map is
  // where it holds together, apart from how its parts are placed.
  int largest_keyframes = 0;
  TrajectoryError largest_error;
  double mapping_s = 0.0;
  int optimisations = 0;                  // over the whole part of the map
  int local_optimisations = 0;            // near a loop that agreed with the map
  double final_optimisation_s = 0.0;      // every part over all its links, at the end
  std::vector<StampedPose> estimate;      // the keyframes' poses at the end
  std::vector<StampedPose> ground_truth;  // and their true poses
  std::vector<MapperLink> links;          // every link the mapper made, at the end
};

// One link against ground truth: the pose graph's edge error r (E = Exp(r) M, E the true
// relative pose) and its chi-square r^T W r under the information the link claims.
struct LinkError {
  double error_m = 0.0;
  double error_deg = 0.0;
  double chi2 = 0.0;
};

Eigen::Isometry3d TruthOf(const MapperLink& link, const std::vector<StampedPose>& truths) {
  return truths[static_cast<size_t>(link.from)].world_from_cam.inverse() *
         truths[static_cast<size_t>(link.to)].world_from_cam;
}

LinkError ErrorOf(const MapperLink& link, const Eigen::Isometry3d& truth) {
  const Eigen::Matrix<double, 6, 1> r = LogSe3(truth * link.to_in_from.inverse());
  return {r.head<3>().norm(), RadToDeg(r.tail<3>().norm()), r.dot(link.information * r)};
}

// The kinds of link a walk makes, each with its own source of error.
const char* LinkKind(const MapperLink& link) {
  if (link.type == LinkType::kOdometry) return link.to == link.from + 1 ? "odometry" : "extra";
  return LinkTypeName(link.type);
}

// How far each kind of link is off by ground truth and how far its information says it is:
// for an honest information the chi-square of a 6-dof error has median 5.35, so "x N" says the
// link claims N times the precision it has (in squared sigmas).
void PrintLinkCalibration(const RunResult& run) {
  std::map<std::string, std::vector<LinkError>> kinds;
  for (const MapperLink& link : run.links) {
    if (!link.active) continue;
    kinds[LinkKind(link)].push_back(ErrorOf(link, TruthOf(link, run.ground_truth)));
  }
  for (const auto& [kind, errors] : kinds) {
    std::vector<double> metres, degrees, chi2;
    for (const LinkError& error : errors) {
      metres.push_back(1e3 * error.error_m);
      degrees.push_back(error.error_deg);
      chi2.push_back(error.chi2);
    }
    std::printf(
        "links %-13s %5zu: error p50 %.1f mm %.2f deg, p90 %.1f mm %.2f deg; chi2 p50 %.1f "
        "(x%.1f), p90 %.1f\n",
        kind.c_str(), errors.size(), Median(metres), Median(degrees), Percentile(metres, 0.9),
        Percentile(degrees, 0.9), Median(chi2), Median(chi2) / 5.35, Percentile(chi2, 0.9));
  }
}

// --trajectory-out: the estimate to FILE and the ground truth to FILE.gt, both TUM, to study
// where the error lies.
void WriteTrajectories(const RunResult& run, const std::string& path) {
  if (path.empty()) return;
  WriteTumTrajectory(path, run.estimate, "slam_benchmark estimate");
  WriteTumTrajectory(path + ".gt", run.ground_truth, "slam_benchmark ground truth");
  // Every link with its error by ground truth, for studying the links' weights.
  std::ofstream links(path + ".links");
  links << "# from to kind inliers active error_m error_deg chi2 true_t(3) est_t(3) r(6)\n";
  for (const MapperLink& link : run.links) {
    const Eigen::Isometry3d truth = TruthOf(link, run.ground_truth);
    const LinkError error = ErrorOf(link, truth);
    links << link.from << ' ' << link.to << ' ' << LinkKind(link) << ' ' << link.inliers << ' '
          << link.active << ' ' << error.error_m << ' ' << error.error_deg << ' ' << error.chi2
          << ' ' << truth.translation().transpose() << ' '
          << link.to_in_from.translation().transpose() << ' '
          << LogSe3(truth * link.to_in_from.inverse()).transpose() << '\n';
  }
  SIGHTMAP_CHECK(links, "cannot write " << path << ".links");
}

// Gives the mapper its next keyframe (and that keyframe's true pose); nullopt at the end.
using KeyframeFeed =
    std::function<std::optional<KeyframeReport>(Mapper& mapper, Eigen::Isometry3d* truth)>;

// Every frame a keyframe, registered by the mapper alone (the 1 Hz capture of the paper).
KeyframeFeed EveryFrame(const std::vector<Frame>& frames) {
  auto next = std::make_shared<size_t>(0);
  return
      [&frames, next](Mapper& mapper, Eigen::Isometry3d* truth) -> std::optional<KeyframeReport> {
        if (*next >= frames.size()) return std::nullopt;
        const Frame& frame = frames[(*next)++];
        *truth = frame.world_from_cam_gt;
        return mapper.AddKeyframe(frame.timestamp_ns, frame.color, frame.depth);
      };
}

// Per-frame tracking figures of a tracked run.
struct TrackingFigures {
  std::vector<double> frame_s;
  double render_s = 0.0;
  TrackerCounters counters;
};

// --frames-out: each tracked frame as the tracker alone placed it, before the mapper optimises
// anything: its pose through the chain of emitted keyframe motions from the first keyframe, which
// starts at its true pose, against the truth. Shows where a stretch of frames drifts and how each
// frame was placed (registered, dense, blind).
class FrameTrace {
 public:
  explicit FrameTrace(const std::string& path) : out_(path) {
    SIGHTMAP_CHECK(out_, "cannot write " << path);
    out_ << "# frame time_s tracking inliers error_m error_deg (the tracker's own chain of "
            "keyframe motions, first keyframe at its true pose)\n";
  }

  void Record(const RgbdFrame& frame, const TrackResult& result) {
    const std::optional<Eigen::Isometry3d> world_from_cam = chain_.Add(result);
    if (!world_from_cam) return;
    const Eigen::Isometry3d error = frame.world_from_cam_gt->inverse() * *world_from_cam;
    out_ << frame.index << ' ' << 1e-9 * static_cast<double>(frame.timestamp_ns) << ' '
         << ToString(result.tracking) << ' ' << result.inliers << ' ' << error.translation().norm()
         << ' ' << RotationAngleDeg(error) << '\n';
  }

 private:
  std::ofstream out_;
  TrackedChain chain_;
};

// Renders the walk frame by frame from `first_frame` (nothing kept but the keyframes' poses) and
// tracks every frame; the keyframes the tracker emits go to the mapper. `trace` (may be null)
// records each frame.
KeyframeFeed TrackedFrames(sim::Simulator& simulator, const TrackerOptions& options,
                           int64_t first_frame, std::shared_ptr<FrameTrace> trace,
                           TrackingFigures* figures) {
  auto tracker = std::make_shared<Tracker>(simulator.options().camera, options);
  auto pending = std::make_shared<std::deque<TrackedKeyframe>>();
  auto next = std::make_shared<int64_t>(first_frame);
  return [&simulator, tracker, pending, next, trace, figures](
             Mapper& mapper, Eigen::Isometry3d* truth) -> std::optional<KeyframeReport> {
    while (pending->empty()) {
      if (*next >= simulator.num_frames()) {
        for (TrackedKeyframe& keyframe : tracker->Finish().keyframes) {
          pending->push_back(std::move(keyframe));
        }
        if (pending->empty()) return std::nullopt;
        break;
      }
      const auto start = std::chrono::steady_clock::now();
      const RgbdFrame frame = simulator.RenderFrame((*next)++);
      figures->render_s += SecondsSince(start);
      TrackResult result = tracker->Track(frame);
      if (trace) trace->Record(frame, result);
      figures->frame_s.push_back(result.total_s);
      for (TrackedKeyframe& keyframe : result.keyframes) pending->push_back(std::move(keyframe));
      figures->counters = tracker->counters();
      if ((*next) % 600 == 0) {
        std::fprintf(stderr, "tracked %lld of %lld frames, %zu keyframes\n",
                     static_cast<long long>(*next), static_cast<long long>(simulator.num_frames()),
                     mapper.NumKeyframes());
      }
    }
    TrackedKeyframe keyframe = std::move(pending->front());
    pending->pop_front();
    *truth = *keyframe.frame.world_from_cam_gt;
    return mapper.AddTrackedKeyframe(std::move(keyframe));
  };
}

// A wrong link between two distant keyframes, "keyframe `id` is where an early keyframe was",
// injected once keyframe `id`'s segment reaches 30 keyframes back: its ends must lie in one
// segment (across segments it would join them, not bend them), the earliest keyframe of this
// one's segment. Returns the link's ends, or nothing when the segment is still too short.
std::optional<std::pair<int64_t, int64_t>> InjectFalseLoop(
    Mapper& mapper, int64_t id, const std::vector<Eigen::Isometry3d>& truths) {
  int64_t from = -1;
  for (int64_t k = 0; k + 30 <= id; ++k) {
    if (mapper.SegmentOf(k) == mapper.SegmentOf(id)) {
      from = k;
      break;
    }
  }
  if (from < 0) return std::nullopt;
  MapperLink link;
  link.from = from;
  link.to = id;
  link.to_in_from = Eigen::Isometry3d::Identity();
  link.information = mapper.Links().back().information;
  link.type = LinkType::kLoopClosure;
  const KeyframeReport injected = mapper.AddExternalLink(link);
  const Eigen::Isometry3d apart =
      truths[static_cast<size_t>(from)].inverse() * truths[static_cast<size_t>(id)];
  std::fprintf(stderr,
               "false loop %lld -> %lld injected (ground truth: %.2f m, %.1f deg apart): %s\n",
               static_cast<long long>(from), static_cast<long long>(id), apart.translation().norm(),
               RotationAngleDeg(apart), injected.links_rejected > 0 ? "rejected" : "kept");
  return std::make_pair(from, id);
}

// Every accepted loop (not the injected one) against ground truth: those more than 10 cm or 3
// degrees off are false.
void CountLoops(const std::optional<std::pair<int64_t, int64_t>>& injected, RunResult* run) {
  for (const MapperLink& link : run->links) {
    // Priors are the motion model's guesses, not place recognition's claims.
    if (link.type == LinkType::kOdometry || link.type == LinkType::kPrior || !link.active) {
      continue;
    }
    if (injected && link.from == injected->first && link.to == injected->second) continue;
    ++run->loops;
    const Eigen::Isometry3d link_truth = TruthOf(link, run->ground_truth);
    const Eigen::Isometry3d error = link_truth.inverse() * link.to_in_from;
    const double error_m = error.translation().norm();
    const double error_deg = RotationAngleDeg(error);
    if (error_m > 0.10 || error_deg > 3.0) {
      ++run->false_loops;
      std::fprintf(stderr, "FALSE loop %lld -> %lld: %.3f m, %.2f deg off\n",
                   static_cast<long long>(link.from), static_cast<long long>(link.to), error_m,
                   error_deg);
    }
  }
}

// The largest part of the map, and its ATE aligned on its own.
void MeasureLargestPart(const Mapper& mapper, RunResult* run) {
  std::map<int, std::vector<StampedPose>> parts;
  for (size_t i = 0; i < run->estimate.size(); ++i) {
    parts[mapper.SegmentOf(static_cast<int64_t>(i))].push_back(run->estimate[i]);
  }
  for (const auto& [segment, poses] : parts) {
    if (static_cast<int>(poses.size()) > run->largest_keyframes) {
      run->largest_keyframes = static_cast<int>(poses.size());
      if (poses.size() >= 3) run->largest_error = EvaluateTrajectory(run->ground_truth, poses);
    }
  }
}

// The mapper's stage times: percentiles, and how the cost per keyframe grows with the map.
void PrintStageTimes(const RunResult& run, const std::vector<MapperStageTimes>& times,
                     const Mapper& mapper, size_t lap_length) {
  auto column = [&times](double MapperStageTimes::*field, size_t from, size_t to) {
    std::vector<double> values;
    for (size_t i = from; i < std::min(to, times.size()); ++i) values.push_back(times[i].*field);
    return values;
  };
  const size_t n = times.size();
  std::printf("keyframes           %d in %.1f s of mapping: %.1f keyframes/s\n", run.keyframes,
              run.mapping_s, run.keyframes / run.mapping_s);
  std::printf("%-20s %9s %9s %9s\n", "stage [ms]", "p50", "p95", "max");
  const std::pair<const char*, double MapperStageTimes::*> stages[] = {
      {"features", &MapperStageTimes::features_s},
      {"matching", &MapperStageTimes::matching_s},
      {"ransac+refine", &MapperStageTimes::ransac_s},
      {"verification", &MapperStageTimes::verification_s},
      {"dense refinement", &MapperStageTimes::dense_s},
      {"place recognition", &MapperStageTimes::place_recognition_s},
      {"optimisation", &MapperStageTimes::optimisation_s},
      {"total", &MapperStageTimes::total_s}};
  for (const auto& [name, field] : stages) {
    const std::vector<double> values = column(field, 0, n);
    std::printf("%-20s %9.2f %9.2f %9.2f\n", name, 1e3 * Percentile(values, 0.5),
                1e3 * Percentile(values, 0.95),
                1e3 * *std::max_element(values.begin(), values.end()));
  }
  if (n >= 300) {
    const double early = Median(column(&MapperStageTimes::total_s, 100, 200));
    const double late = Median(column(&MapperStageTimes::total_s, n - 100, n));
    std::printf("median per keyframe  %.1f ms at keyframes 100-200, %.1f ms at %zu-%zu (x%.2f)\n",
                1e3 * early, 1e3 * late, n - 100, n, late / early);
    // Which stage grows: the mean of each over keyframes [from, to) (a median hides stages
    // that run on some keyframes only).
    const auto mean = [](size_t from, size_t to, const auto& value_of) {
      double sum = 0.0;
      for (size_t i = from; i < to; ++i) sum += value_of(i);
      return sum / static_cast<double>(to - from);
    };
    std::printf("  mean per stage [ms] at 100-200 -> last 100:");
    for (const auto& [name, field] : stages) {
      const auto stage_ms = [&times, field = field](size_t i) { return 1e3 * (times[i].*field); };
      std::printf(" %s %.1f->%.1f,", name, mean(100, 200, stage_ms), mean(n - 100, n, stage_ms));
    }
    std::printf("\n");
    if (lap_length >= 200 && n >= 2 * lap_length) {
      // The same frames on the first lap and the last: what the map's size alone costs.
      const size_t last_lap = n - lap_length;
      const double first = Median(column(&MapperStageTimes::total_s, 100, 200));
      const double again =
          Median(column(&MapperStageTimes::total_s, last_lap + 100, last_lap + 200));
      std::printf(
          "same frames 100-200  median %.1f ms on lap 1 (keyframes 100-200), %.1f ms on lap %zu "
          "(keyframes %zu-%zu): x%.2f\n",
          1e3 * first, 1e3 * again, n / lap_length, last_lap + 100, last_lap + 200, again / first);
    }
    const auto registrations = [&times](size_t i) {
      return static_cast<double>(times[i].registrations);
    };
    const auto points = [&mapper](size_t i) {
      return static_cast<double>(mapper.FeaturesOf(static_cast<int64_t>(i)).NumPoints());
    };
    // Matching is quadratic in the 3D keypoints in view: a richer scene costs more per pair.
    std::printf(
        "  registrations per keyframe, mean: %.2f at 100-200 -> %.2f; 3D keypoints %.0f -> "
        "%.0f\n",
        mean(100, 200, registrations), mean(n - 100, n, registrations), mean(100, 200, points),
        mean(n - 100, n, points));
  }
}

// The run's figures: optimisations, memory, parts, loops, ATE and its sources, RPE.
void PrintRun(const RunResult& run) {
  std::printf(
      "optimisations       %d over the whole part, %d near a loop that agreed, the final one "
      "%.0f ms\n",
      run.optimisations, run.local_optimisations, 1e3 * run.final_optimisation_s);
  std::printf("peak RSS            %.0f MiB\n", PeakRssMiB());
  std::printf("segments            %d\n", run.segments);
  std::printf(
      "loops               %d accepted, %d rejected by the pose graph, %d false "
      "(> 10 cm or > 3 deg from ground truth)\n",
      run.loops, run.loops_rejected, run.false_loops);
  std::printf("ATE                 rmse %.4f m, mean %.4f, median %.4f, max %.4f (%d poses)\n",
              run.error.ate_rmse_m, run.error.ate_mean_m, run.error.ate_median_m,
              run.error.ate_max_m, run.error.matched_poses);
  const ErrorSources sources = FindErrorSources(run.error);
  const ErrorConcentration& concentration = sources.concentration;
  std::printf(
      "ATE sources         Sim(3) scale %.5f (rmse %.4f m after it); the worst %d poses hold "
      "%.0f%% of the squared error (rmse %.4f m without them); worst 10 s:",
      run.error.sim3_scale, run.error.sim3_ate_rmse_m, concentration.worst_poses,
      100.0 * concentration.worst_share, concentration.rest_rmse_m);
  for (const ErrorStretch& stretch : sources.stretches) {
    std::printf(" t %.0f-%.0f s %.3f m (max %.3f)", stretch.start_s, stretch.end_s, stretch.mean_m,
                stretch.max_m);
  }
  std::printf("\n");
  std::printf("RPE                 %.4f m/m, %.3f deg/m\n", run.error.rpe_trans_per_m,
              run.error.rpe_rot_deg_per_m);
  std::printf("building's axes     seen by %d of %d keyframes (a rotation prior each)\n",
              run.manhattan_keyframes, run.keyframes);
  std::printf("largest part        %d keyframes, ATE rmse %.4f m, max %.4f aligned on its own\n",
              run.largest_keyframes, run.largest_error.ate_rmse_m, run.largest_error.ate_max_m);
  PrintLinkCalibration(run);
}

// `lap_length` > 0: the frames are one walk of that many frames repeated (--laps).
RunResult Run(const KeyframeFeed& feed, const Intrinsics& camera, const MapperOptions& options,
              int false_loop_at, bool verbose, size_t lap_length = 0) {
  Mapper mapper(camera, options);
  std::vector<MapperStageTimes> times;
  std::vector<Eigen::Isometry3d> truths;  // by keyframe id
  RunResult run;
  std::optional<std::pair<int64_t, int64_t>> injected;
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  for (size_t i = 0;; ++i) {
    const std::optional<KeyframeReport> next = feed(mapper, &truth);
    if (!next) break;
    const KeyframeReport& report = *next;
    truths.push_back(truth);
    times.push_back(report.times);
    run.mapping_s += report.times.total_s;
    run.loops_rejected += report.links_rejected;
    if (report.optimised)
      ++(report.optimised_locally ? run.local_optimisations : run.optimisations);
    if (verbose && (report.state != TrackingState::kTracking || report.loop_closed ||
                    report.links_rejected > 0)) {
      std::fprintf(stderr, "keyframe %lld: %s%s%s %s\n", static_cast<long long>(report.id),
                   ToString(report.state), report.loop_closed ? ", loop closed" : "",
                   report.links_rejected > 0 ? ", a link rejected" : "",
                   report.odometry_failure.c_str());
    }
    if (false_loop_at >= 0 && static_cast<int>(i) >= false_loop_at && !injected) {
      injected = InjectFalseLoop(mapper, static_cast<int64_t>(i), truths);
      run.false_loop_injected = injected.has_value();
    }
  }
  // As `sightmap map` ends a capture.
  const KeyframeReport whole = mapper.OptimiseWhole();
  run.loops_rejected += whole.links_rejected;
  run.final_optimisation_s = whole.times.optimisation_s;
  run.keyframes = static_cast<int>(mapper.NumKeyframes());
  run.segments = mapper.NumSegments();
  run.manhattan_keyframes = mapper.NumManhattanKeyframes();
  run.estimate = mapper.Trajectory();
  for (size_t i = 0; i < truths.size(); ++i) {
    run.ground_truth.push_back({run.estimate[i].timestamp_ns, truths[i]});
  }
  run.error = EvaluateTrajectory(run.ground_truth, run.estimate);
  run.links = mapper.Links();
  CountLoops(injected, &run);
  MeasureLargestPart(mapper, &run);
  if (verbose) {
    PrintStageTimes(run, times, mapper, lap_length);
    PrintRun(run);
  }
  return run;
}

// 3D keypoints of `a` that reappear in `b`: moved into b's camera by the true motion, a keypoint of
// b with its own 3D point lies within `radius_px` and `max_distance_m`. Whatever the descriptors
// do, a pair sharing fewer than the registration's minimum inliers cannot be registered from
// features alone.
int RepeatableKeypoints(const Features& a, const Features& b, const Eigen::Isometry3d& b_from_a,
                        const Intrinsics& camera, double radius_px = 3.0,
                        double max_distance_m = 0.05) {
  int repeatable = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a.has_point[i]) continue;
    const Eigen::Vector3d in_b = b_from_a * a.points_cam[i];
    if (in_b.z() < 0.1) continue;
    const Eigen::Vector2d uv = camera.Project(in_b);
    for (size_t j = 0; j < b.size(); ++j) {
      if (!b.has_point[j]) continue;
      const Eigen::Vector2d pixel(b.keypoints[j].pt.x, b.keypoints[j].pt.y);
      if ((pixel - uv).norm() <= radius_px && (b.points_cam[j] - in_b).norm() <= max_distance_m) {
        ++repeatable;
        break;
      }
    }
  }
  return repeatable;
}

// Consecutive frames by ground truth: how far apart, how much they share, whether registration
// (the mapper's options, no prior) bridges them, and how far off the registered pairs are. The
// pairs' errors measure a change to registration without the chaos of a whole map, where a few
// fragile stretches flip by tens of centimetres on any small change.
void ReportOverlap(const std::vector<Frame>& frames, const Intrinsics& camera,
                   const MapperOptions& options) {
  std::vector<Features> features;
  for (const Frame& frame : frames) {
    features.push_back(ExtractFeatures(frame.color, frame.depth, camera, options.features));
  }
  std::vector<double> angles_deg, distances_m, points;
  int unbridgeable = 0, unbridgeable_registered = 0, bridgeable_refused = 0;
  std::vector<double> error_mm, error_deg;
  int wrong = 0;  // registered more than 10 cm or 3 degrees off
  for (size_t i = 0; i < features.size(); ++i) {
    points.push_back(static_cast<double>(features[i].NumPoints()));
  }
  for (size_t i = 1; i < frames.size(); ++i) {
    const Eigen::Isometry3d b_from_a =
        frames[i].world_from_cam_gt.inverse() * frames[i - 1].world_from_cam_gt;
    angles_deg.push_back(RotationAngleDeg(b_from_a));
    distances_m.push_back(b_from_a.translation().norm());
    const int repeatable = RepeatableKeypoints(features[i - 1], features[i], b_from_a, camera);
    const RegistrationResult result =
        RegisterRgbd(features[i - 1], features[i], frames[i - 1].depth, frames[i].depth, camera,
                     options.registration);
    const bool bridgeable = repeatable >= options.registration.min_inliers;
    if (!bridgeable) ++unbridgeable;
    if (!bridgeable && result.success) ++unbridgeable_registered;
    if (bridgeable && !result.success) ++bridgeable_refused;
    if (result.success) {
      const Eigen::Isometry3d error = b_from_a.inverse() * result.target_from_source;
      error_mm.push_back(1e3 * error.translation().norm());
      error_deg.push_back(RotationAngleDeg(error));
      if (error_mm.back() > 100.0 || error_deg.back() > 3.0) ++wrong;
    }
  }
  const auto count_below = [](const std::vector<double>& values, double limit) {
    return std::count_if(values.begin(), values.end(), [&](double v) { return v < limit; });
  };
  const size_t pairs = angles_deg.size();
  std::printf("overlap of consecutive frames (ground truth)\n");
  std::printf(
      "  motion            p50 %.1f deg %.2f m, p95 %.1f deg %.2f m; %ld of %zu pairs over 30 "
      "deg\n",
      Median(angles_deg), Median(distances_m), Percentile(angles_deg, 0.95),
      Percentile(distances_m, 0.95),
      static_cast<long>(pairs - static_cast<size_t>(count_below(angles_deg, 30.0))), pairs);
  std::printf("  3D keypoints      p50 %.0f per frame; %ld of %zu frames under 150, %ld under 50\n",
              Median(points), static_cast<long>(count_below(points, 150.0)), points.size(),
              static_cast<long>(count_below(points, 50.0)));
  std::printf(
      "  unbridgeable      %d of %zu pairs share fewer than %d repeatable 3D keypoints "
      "(%d of them registered anyway)\n",
      unbridgeable, pairs, options.registration.min_inliers, unbridgeable_registered);
  std::printf("  refused           %d of %zu bridgeable pairs not registered\n", bridgeable_refused,
              pairs - static_cast<size_t>(unbridgeable));
  if (error_mm.empty()) return;
  std::printf(
      "  registered error  %zu pairs: p50 %.2f mm %.3f deg, p75 %.2f mm, p95 %.1f mm %.2f deg; "
      "%d more than 10 cm or 3 deg off\n",
      error_mm.size(), Median(error_mm), Median(error_deg), Percentile(error_mm, 0.75),
      Percentile(error_mm, 0.95), Percentile(error_deg, 0.95), wrong);
}

void PrintFalseLoop(const RunResult& clean, const RunResult& injected, int at) {
  if (!injected.false_loop_injected) {
    std::printf("false loop          not injected: no segment of 30 keyframes after %d\n", at);
    return;
  }
  std::printf(
      "false loop          ATE rmse %.4f m with it, %.4f m without (%+.1f%%); largest part "
      "%.4f m with it, %.4f m without\n",
      injected.error.ate_rmse_m, clean.error.ate_rmse_m,
      100.0 * (injected.error.ate_rmse_m / clean.error.ate_rmse_m - 1.0),
      injected.largest_error.ate_rmse_m, clean.largest_error.ate_rmse_m);
}

// How well each frame's depth gives the building's axes (FitManhattanFrame), against the
// simulator's ground truth (its walls run along the world's x and y, z up).
void ReportManhattanFits(const std::vector<Frame>& frames, const Intrinsics& camera,
                         const ManhattanOptions& options) {
  std::vector<double> errors_deg;
  for (const Frame& frame : frames) {
    const std::optional<ManhattanFit> fit = FitManhattanFrame(frame.depth, camera, options);
    if (!fit) continue;
    errors_deg.push_back(
        RadToDeg(NearestManhattanRotation(Eigen::Matrix3d::Identity(), fit->cam_from_manhattan,
                                          frame.world_from_cam_gt.linear())
                     .second));
  }
  std::printf("building's axes     shown by %zu of %zu frames", errors_deg.size(), frames.size());
  if (!errors_deg.empty()) {
    std::printf(", rotation error p50 %.3f deg, p90 %.3f, p99 %.3f, max %.3f",
                Percentile(errors_deg, 0.5), Percentile(errors_deg, 0.9),
                Percentile(errors_deg, 0.99), Percentile(errors_deg, 1.0));
  }
  std::printf("\n");
}

// The options `sightmap map --config` reads, as far as SLAM goes: its "mapper" block and its
// "tracking" block's "tracker".
void ReadConfig(const std::string& path, MapperOptions* mapper, TrackerOptions* tracker) {
  std::ifstream file(path);
  SIGHTMAP_CHECK(file, "cannot read the config " << path);
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(file);
    if (json.contains("mapper")) *mapper = json.at("mapper").get<MapperOptions>();
    if (json.contains("tracking") && json.at("tracking").contains("tracker")) {
      *tracker = json.at("tracking").at("tracker").get<TrackerOptions>();
    }
  } catch (const nlohmann::json::exception& error) {
    SIGHTMAP_THROW(InvalidArgument, "the config " << path << " is not valid: " << error.what());
  }
}

// --track: the walk tracked frame by frame, as `sightmap map` does (on one thread here, so the
// times are the tracker's and the mapper's alone).
int RunTrackedBenchmark(const sim::SimulatorOptions& sim_options, const MapperOptions& options,
                        const TrackerOptions& tracker, bool false_loop,
                        const std::string& trajectory_out, int64_t first_frame,
                        const std::string& frames_out) {
  sim::Simulator simulator(sim_options);
  SIGHTMAP_CHECK(first_frame >= 0 && first_frame < simulator.num_frames(),
                 "--first-frame " << first_frame << " is not a frame of the "
                                  << simulator.num_frames() << "-frame walk");
  std::printf("simulator office, %s, session %d, seed %llu, frames %lld-%lld at %g Hz, tracked\n",
              sim::ToString(sim_options.trajectory), sim_options.session,
              static_cast<unsigned long long>(sim_options.seed),
              static_cast<long long>(first_frame),
              static_cast<long long>(simulator.num_frames() - 1), sim_options.fps);
  TrackingFigures figures;
  const auto trace = frames_out.empty() ? nullptr : std::make_shared<FrameTrace>(frames_out);
  const auto start = std::chrono::steady_clock::now();
  const RunResult clean = Run(TrackedFrames(simulator, tracker, first_frame, trace, &figures),
                              simulator.options().camera, options, -1, true);
  WriteTrajectories(clean, trajectory_out);
  const double wall_s = SecondsSince(start);
  const double walk_s = static_cast<double>(simulator.num_frames() - first_frame) / sim_options.fps;
  const TrackerCounters& c = figures.counters;
  std::printf(
      "tracking            %lld frames: %lld before the first keyframe, %lld registered (%lld "
      "of them rescued by dense alignment), %lld dense (%lld of them a second or more apart, by "
      "the dense search), %lld blind; %lld keyframes (%lld early, "
      "%lld on the motion model)\n",
      static_cast<long long>(c.frames), static_cast<long long>(c.before_start),
      static_cast<long long>(c.registered), static_cast<long long>(c.rescued),
      static_cast<long long>(c.dense), static_cast<long long>(c.searched),
      static_cast<long long>(c.blind), static_cast<long long>(c.keyframes),
      static_cast<long long>(c.early_keyframes), static_cast<long long>(c.prior_keyframes));
  std::printf("tracking per frame  p50 %.1f ms, p95 %.1f ms, max %.1f ms\n",
              1e3 * Percentile(figures.frame_s, 0.5), 1e3 * Percentile(figures.frame_s, 0.95),
              1e3 * Percentile(figures.frame_s, 1.0));
  std::printf(
      "speed               %.0f s of walk in %.0f s on one thread (%.0f s rendering): x%.2f real "
      "time without rendering\n",
      walk_s, wall_s, figures.render_s, walk_s / std::max(1e-9, wall_s - figures.render_s));
  std::printf(
      "largest part ratio  %.4f\n",
      clean.keyframes > 0 ? static_cast<double>(clean.largest_keyframes) / clean.keyframes : 0.0);
  if (false_loop) {
    sim::Simulator again(sim_options);
    TrackingFigures ignored;
    const int at = clean.keyframes * 3 / 4;
    const RunResult injected = Run(TrackedFrames(again, tracker, first_frame, nullptr, &ignored),
                                   again.options().camera, options, at, false);
    PrintFalseLoop(clean, injected, at);
  }
  return 0;
}

int Main(int argc, char** argv) {
  CLI::App app{"SLAM on the synthetic building at 1 Hz: speed and accuracy"};
  std::string trajectory = "handheld";
  int session = 1;
  uint64_t seed = 1;
  int64_t frames_wanted = 600;
  bool false_loop = false;
  bool overlap = false;
  bool manhattan = false;
  double fps = 1.0;
  bool no_walk_check = false;
  int local_loop_hops = -1;
  int laps = 1;
  bool track = false;
  int64_t first_frame = 0;
  std::string frames_out;
  std::string trajectory_out;
  app.add_option("--trajectory", trajectory, "handheld, robot or survey")
      ->check(CLI::IsMember({"handheld", "robot", "survey"}));
  app.add_option("--session", session, "simulator session (>= 1)");
  app.add_option("--seed", seed, "simulator seed");
  app.add_option("--frames", frames_wanted, "keyframes (frames of the walk at --fps)");
  app.add_flag("--false-loop", false_loop,
               "also run again with a wrong loop injected halfway and compare the ATE");
  app.add_flag("--manhattan", manhattan,
               "how far the building's axes fitted to each frame's depth are from the truth "
               "(mapper.manhattan options), then stop");
  app.add_flag("--overlap", overlap,
               "first report what consecutive frames share by ground truth, and how many pairs "
               "registration bridges");
  app.add_option("--fps", fps,
                 "frames per second of the walk; every frame is mapped as a keyframe");
  app.add_option("--local-loop-hops", local_loop_hops,
                 "optimise a loop over the keyframes this many links from its ends first (0: "
                 "always over the whole map)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--no-walk-check", no_walk_check,
               "join segments without checking that the walk stays possible (for comparison)");
  app.add_option("--laps", laps,
                 "walk the frames this many times (the frames shared, not rendered again), to "
                 "compare the cost of the same frames in a small and a large map")
      ->check(CLI::PositiveNumber);
  app.add_flag("--track", track,
               "track every frame of the walk at --fps (rendered as it goes, not kept) and map the "
               "keyframes the tracker emits at 1 Hz and where the overlap runs out, as `sightmap "
               "map` does");
  app.add_option("--first-frame", first_frame,
                 "with --track: start the walk at this frame (the stretch up to --frames)")
      ->check(CLI::NonNegativeNumber);
  app.add_option(
      "--frames-out", frames_out,
      "with --track: write each frame's tracking (registered, dense, blind), inliers and "
      "the tracker's own pose error against the truth, before the mapper, to FILE");
  std::string config_path;
  app.add_option("--config", config_path,
                 "read the mapper's and the tracker's options from this JSON (`sightmap map "
                 "--print-config`'s blocks \"mapper\" and \"tracking\".\"tracker\"; either may be "
                 "missing)")
      ->check(CLI::ExistingFile);
  app.add_option(
      "--trajectory-out", trajectory_out,
      "write the keyframes' final poses to FILE and their true poses to FILE.gt (TUM), and "
      "every link against ground truth to FILE.links");
  CLI11_PARSE(app, argc, argv);

  sim::SimulatorOptions sim_options;
  sim_options.trajectory = sim::ParseTrajectoryKind(trajectory);
  sim_options.session = session;
  sim_options.seed = seed;
  sim_options.fps = fps;
  sim_options.frames = frames_wanted;
  sim::Simulator simulator(sim_options);
  const Intrinsics camera = simulator.options().camera;
  MapperOptions options;
  TrackerOptions tracker;
  tracker.features = options.features;
  tracker.registration = options.registration;
  tracker.depth_downscale = options.depth_downscale;
  if (!config_path.empty()) ReadConfig(config_path, &options, &tracker);
  if (no_walk_check) options.walk_max_gap_s = 0.0;
  if (local_loop_hops >= 0) options.local_loop_hops = local_loop_hops;
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK_OPTIONS(tracker);
  if (!track && (first_frame > 0 || !frames_out.empty())) {
    SIGHTMAP_THROW(InvalidArgument, "--first-frame and --frames-out need --track");
  }
  if (track) {
    return RunTrackedBenchmark(sim_options, options, tracker, false_loop, trajectory_out,
                               first_frame, frames_out);
  }
  std::vector<Frame> frames;
  const auto render_start = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < simulator.num_frames(); ++i) {
    RgbdFrame frame = simulator.RenderFrame(i);
    frames.push_back({frame.timestamp_ns, frame.color, frame.depth, *frame.world_from_cam_gt});
    if ((i + 1) % 100 == 0) {
      std::fprintf(stderr, "rendered %lld of %lld frames\n", static_cast<long long>(i + 1),
                   static_cast<long long>(simulator.num_frames()));
    }
  }
  std::fprintf(stderr, "rendering took %.1f s\n", SecondsSince(render_start));
  std::printf("simulator office, %s, session %d, seed %llu, %zu keyframes at %g Hz\n",
              trajectory.c_str(), session, static_cast<unsigned long long>(seed), frames.size(),
              fps);
  if (overlap) ReportOverlap(frames, camera, options);
  if (manhattan) {
    ReportManhattanFits(frames, camera, options.manhattan);
    return 0;
  }
  const size_t lap_length = frames.size();
  for (int lap = 1; lap < laps; ++lap) {
    const TimestampNs offset = frames[lap_length - 1].timestamp_ns + 1'000'000'000;
    for (size_t i = 0; i < lap_length; ++i) {
      Frame again = frames[i];
      again.timestamp_ns += offset * lap;
      frames.push_back(again);
    }
  }
  const RunResult clean =
      Run(EveryFrame(frames), camera, options, -1, true, laps > 1 ? lap_length : 0);
  WriteTrajectories(clean, trajectory_out);
  if (false_loop) {
    const RunResult injected =
        Run(EveryFrame(frames), camera, options, static_cast<int>(frames.size()) * 3 / 4, false);
    PrintFalseLoop(clean, injected, static_cast<int>(frames.size()) * 3 / 4);
  }
  return 0;
}

}  // namespace
}  // namespace sightmap::slam

int main(int argc, char** argv) {
  try {
    return sightmap::slam::Main(argc, argv);
  } catch (const std::exception& error) {
    std::cerr << "error: " << error.what() << "\n";
    return 1;
  }
}
