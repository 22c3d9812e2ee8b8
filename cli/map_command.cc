// sightmap map --source SOURCE --model FILE [...]: the capture appliance end to end (issue 8). Maps
// a sensor, recording, folder or the simulator into a model (resuming it when it holds keyframes),
// with a status line on stderr and a summary on stdout. Ctrl-C or SIGTERM stops gracefully (exit
// 0 with the summary); a second one exits at once, the model keeping every committed keyframe.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "cli/stop_signals.h"
#include "core/check.h"
#include "mapping/mapping_session.h"

namespace sightmap::cli {
namespace {

std::string Megabytes(int64_t bytes) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(1) << static_cast<double>(bytes) / 1e6 << " MB";
  return out.str();
}

std::string TrackingText(const mapping::MappingProgress& progress) {
  if (progress.paused) return "paused";
  if (progress.resumed && !progress.joined_stored_map) {
    return progress.keyframes == 0 ? "resuming" : "not yet relocalised into the stored map";
  }
  return ToString(progress.tracking);
}

// The status line: a progress bar when the source's length is known.
class StatusLine {
 public:
  StatusLine() : tty_(isatty(STDERR_FILENO) != 0) {}

  void Update(const mapping::MappingProgress& progress) {
    std::ostringstream line;
    if (progress.frames_total && *progress.frames_total > 0) {
      const double done = std::clamp(
          static_cast<double>(progress.frames_passed) / static_cast<double>(*progress.frames_total),
          0.0, 1.0);
      constexpr int kWidth = 20;
      const int filled = static_cast<int>(done * kWidth);
      line << "[" << std::string(static_cast<size_t>(filled), '#')
           << std::string(static_cast<size_t>(kWidth - filled), '.') << "] " << std::setw(3)
           << static_cast<int>(done * 100.0) << "% ";
    }
    line << progress.keyframes << " keyframes (" << std::fixed << std::setprecision(2)
         << progress.keyframes_per_s << "/s), " << TrackingText(progress) << ", " << progress.loops
         << " loops, " << progress.dropped_frames << " dropped";
    if (progress.optimising_whole_map) line << ", optimising the whole map";
    if (tty_) {
      std::cerr << "\r" << line.str() << "\033[K" << std::flush;
      shown_ = true;
      if (progress.finished) End();
    } else if (progress.finished || progress.optimising_whole_map ||
               progress.elapsed_s - last_printed_s_ >= 10.0) {
      // Logs and pipes get a line every 10 s rather than one per keyframe.
      std::cerr << line.str() << "\n";
      last_printed_s_ = progress.elapsed_s;
    }
  }

  void End() {
    if (shown_) std::cerr << "\n";
    shown_ = false;
  }

 private:
  bool tty_;
  bool shown_ = false;
  double last_printed_s_ = 0.0;
};

nlohmann::json SummaryJson(const mapping::MappingSummary& summary) {
  nlohmann::json json;
  json["reason"] = ToString(summary.reason);
  json["reason_detail"] = summary.reason_detail;
  json["source_kind"] = summary.source_kind;
  json["session"] = summary.session;
  json["resumed"] = summary.resumed;
  json["restored_keyframes"] = summary.restored_keyframes;
  json["interrupted_sessions_marked"] = summary.interrupted_sessions_marked;
  json["joined_stored_map"] = summary.joined_stored_map;
  json["keyframes"] = summary.keyframes;
  json["model_keyframes"] = summary.model_keyframes;
  json["loops"] = summary.loops;
  json["segments"] = summary.segments;
  json["largest_segment_keyframes"] = summary.largest_segment_keyframes;
  json["largest_part_ratio"] = summary.largest_part_ratio;
  json["prior_links"] = summary.prior_links;
  json["axes_keyframes"] = summary.axes_keyframes;
  json["tracked_frames"] = summary.tracked_frames;
  json["dense_frames"] = summary.dense_frames;
  json["dense_at_rest_frames"] = summary.dense_at_rest_frames;
  json["blind_frames"] = summary.blind_frames;
  json["early_keyframes"] = summary.early_keyframes;
  json["frames_before_start"] = summary.frames_before_start;
  json["track_median_ms"] = summary.track_median_ms;
  json["track_p95_ms"] = summary.track_p95_ms;
  json["keyframe_median_ms"] = summary.keyframe_median_ms;
  json["keyframe_p95_ms"] = summary.keyframe_p95_ms;
  json["dropped_frames"] = summary.dropped_frames;
  json["unpaired_frames"] = summary.unpaired_frames;
  json["frames_read"] = summary.frames_read;
  json["frames_skipped"] = summary.frames_skipped;
  json["continued_after_s"] =
      summary.continued_after_s ? nlohmann::json(*summary.continued_after_s) : nlohmann::json();
  json["links_rejected_after_commit"] = summary.links_rejected_after_commit;
  json["links_reactivated_at_end"] = summary.links_reactivated_at_end;
  json["final_optimisation_s"] = summary.final_optimisation_s;
  json["ate_rmse_m"] = summary.ate_rmse_m ? nlohmann::json(*summary.ate_rmse_m) : nlohmann::json();
  json["ate_max_m"] = summary.ate_max_m ? nlohmann::json(*summary.ate_max_m) : nlohmann::json();
  json["ate_poses"] = summary.ate_poses;
  json["elapsed_s"] = summary.elapsed_s;
  json["keyframes_per_s"] = summary.keyframes_per_s;
  json["model_bytes"] = summary.model_bytes;
  json["ply_points"] = summary.ply_points;
  json["ply"] = summary.ply_path;
  json["trajectory"] = summary.trajectory_path;
  json["view"] = summary.view;
  json["peak_rss_mib"] = summary.peak_rss_mib;
  return json;
}

void PrintSummary(const mapping::MappingSummary& summary, const std::string& model_path,
                  std::ostream& out) {
  out << std::fixed << std::setprecision(1);
  out << "map: " << summary.keyframes << " keyframes in " << summary.elapsed_s << " s ("
      << std::setprecision(2) << summary.keyframes_per_s
      << " keyframes/s); stopped: " << ToString(summary.reason);
  if (!summary.reason_detail.empty()) out << " (" << summary.reason_detail << ")";
  out << "\n";
  out << "  model       " << model_path << ": " << summary.model_keyframes << " keyframes, session "
      << summary.session_number << ", " << Megabytes(summary.model_bytes) << "\n";
  if (summary.resumed) {
    out << "  resumed     " << summary.restored_keyframes << " keyframes restored";
    if (summary.interrupted_sessions_marked > 0) {
      out << ", " << summary.interrupted_sessions_marked
          << " crashed session(s) marked interrupted";
    }
    out << "; "
        << (summary.joined_stored_map
                ? "this session relocalised into the stored map"
                : "this session did not relocalise into the stored map: its keyframes "
                  "are kept as a separate segment")
        << "\n";
  }
  if (summary.continued_after_s) {
    out << std::setprecision(3) << "  continued   after the last stored frame of this source (t = "
        << *summary.continued_after_s << " s; " << summary.frames_skipped << " frames skipped)\n"
        << std::setprecision(1);
  }
  out << "  loops       " << summary.loops << "\n";
  out << "  segments    " << summary.segments;
  if (summary.segments > 1) {
    out << " (the largest holds " << summary.largest_segment_keyframes << " of "
        << summary.model_keyframes << " keyframes)";
  }
  out << "\n";
  if (summary.tracked_frames > 0) {
    out << "  tracked     " << summary.tracked_frames << " frames (" << summary.dense_frames
        << " by dense odometry, " << summary.dense_at_rest_frames << " of them at rest, "
        << summary.blind_frames << " by the motion model alone; " << summary.prior_links
        << " prior links, " << summary.early_keyframes << " early keyframes, "
        << summary.axes_keyframes << " showing the building's axes); " << std::setprecision(1)
        << summary.track_median_ms << " ms median, " << summary.track_p95_ms
        << " ms p95 per frame\n";
    if (summary.frames_before_start > 0) {
      out << "  started     after " << summary.frames_before_start
          << (summary.frames_before_start == 1 ? " frame" : " frames")
          << " too bare to anchor the map (aim at furniture or a corner when you start)\n";
    }
  }
  out << std::setprecision(1) << "  keyframe    " << summary.keyframe_median_ms << " ms median, "
      << summary.keyframe_p95_ms << " ms p95 to map\n";
  out << "  dropped     " << summary.dropped_frames << " frames";
  if (summary.unpaired_frames > 0) out << " (" << summary.unpaired_frames << " more unpaired)";
  out << "\n";
  if (summary.ate_rmse_m) {
    out << std::setprecision(3) << "  ATE         " << *summary.ate_rmse_m << " m rmse (max "
        << *summary.ate_max_m << " m) over " << summary.ate_poses << " keyframes\n";
  }
  if (!summary.ply_path.empty()) {
    out << "  PLY         " << summary.ply_path << ": " << summary.ply_points << " points\n";
  }
  if (!summary.trajectory_path.empty()) {
    out << "  trajectory  " << summary.trajectory_path << "\n";
  }
  if (!summary.view.empty()) out << "  progress    " << summary.view << "\n";
  out << std::setprecision(0) << "  peak RSS    " << summary.peak_rss_mib << " MiB\n";
}

}  // namespace

int RunMap(int argc, char** argv) {
  CLI::App app(
      "Map a SOURCE into a MODEL: keyframes at --rate, registered with loop-closure checks, "
      "written as they come; the PLY and trajectory at the end. An existing MODEL is resumed.",
      "sightmap map");
  mapping::MappingOptions options;
  options.source = "openni://";
  bool preview = false;
  bool headless = false;
  bool json = false;
  app.add_option("--source", options.source,
                 "openni:// | openni://URI | FILE.oni | tum:DIR | 3dmatch:DIR | sim:NAME[?...] "
                 "(default: the first sensor)");
  auto* model_option =
      app.add_option("--model", options.model_path, "the model file (SQLite), created or resumed");
  app.add_option("--ply", options.ply_path, "write the point cloud here at the end");
  app.add_option("--rate", options.sampler.rate_hz,
                 "keyframes per second of source time [Hz]; 0 makes every frame a keyframe")
      ->check(Within(0, 1000, "Hz"))
      ->capture_default_str();
  auto* preview_flag = app.add_flag("--preview", preview, "show the preview window (fail without)");
  auto* headless_flag =
      app.add_flag("--headless", headless, "no window; progress only as --progress-png images");
  preview_flag->excludes(headless_flag);
  app.add_option("--progress-png", options.view.progress_png,
                 "rewrite this PNG of the map every 10 keyframes and at the end");
  app.add_option("--trajectory-out", options.trajectory_path,
                 "write every keyframe's pose here at the end (TUM format)");
  app.add_flag("--realtime", options.source_options.realtime,
               "play a recording at its recorded pace, as a live sensor (frames the mapper cannot "
               "keep up with are dropped)");
  auto* start_frame_option =
      app.add_option("--start-frame", options.start_frame,
                     "skip the source's first N frames (default: from 0, or when resuming a model "
                     "from the same recording or walk, after its last stored frame)")
          ->check(Within(0, 1e12));
  app.add_option("--max-keyframes", options.max_keyframes,
                 "stop after N keyframes of this session (0: no limit)")
      ->check(Within(0, 1e12));
  app.add_option("--calib", options.source_options.calibration_file,
                 "JSON calibration overriding intrinsics and depth-to-colour registration")
      ->check(CLI::ExistingFile);
  app.add_flag("--ground-truth-poses", options.ground_truth_poses,
               "take each keyframe's pose from the source's ground truth instead of registering "
               "it (evaluates photo localisation apart from SLAM; simulator or TUM folders)");
  bool no_tracking = false;
  app.add_option("--track-every", options.track_every,
                 "track every Nth frame of the source (1: every frame)")
      ->check(Within(1, 1000))
      ->capture_default_str();
  app.add_flag("--no-tracking", no_tracking,
               "register keyframes to each other only, not the frames in between (the paper's "
               "1 Hz capture)");
  app.add_flag("--json", json, "print the summary as one JSON object (stable keys)");
  bool print_config = false;
  AddConfigOptions(app, options, print_config);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  // What the flags imply, over what a --config file set.
  if (start_frame_option->count() > 0) options.continue_replay = false;
  if (options.source_options.realtime) options.live = true;
  if (no_tracking) options.tracking.track = false;
  if (preview) options.view.choice = mapping::ViewChoice::kPreview;
  if (headless) options.view.choice = mapping::ViewChoice::kHeadless;
  const bool has_display = std::getenv("DISPLAY") || std::getenv("WAYLAND_DISPLAY");
  // Nothing to draw into (no window and no image file): no view at all, whatever a config says.
  options.show_view = !options.view.progress_png.empty() ||
                      options.view.choice == mapping::ViewChoice::kPreview ||
                      (options.view.choice == mapping::ViewChoice::kAuto && has_display);
  if (print_config) return PrintConfig(options);
  if (const int code = RequireGiven(app, {model_option}); code >= 0) return code;
  // Before any thread exists; a Ctrl-C from here on waits for the session to take it.
  std::atomic<bool> stop_requested{false};
  StopSignalWatcher watcher(
      "sightmap map",
      "\nsightmap map: stopping after the keyframe in hand (Ctrl-C again to exit at once)\n");

  // The outputs are checked (their folders made) before any work: a typo in --ply must not cost
  // a mapping run.
  MakeParentFolder(options.model_path, "--model");
  CheckOutputFile(options.ply_path, "--ply");
  CheckOutputFile(options.trajectory_path, "--trajectory-out");
  CheckOutputFile(options.view.progress_png, "--progress-png");

  mapping::MappingSession session(options);
  session.SetInterruptFlag(&stop_requested);
  watcher.Start([&stop_requested] { stop_requested = true; });
  StatusLine status;
  session.SetProgressCallback(
      [&status](const mapping::MappingProgress& progress) { status.Update(progress); });
  mapping::MappingSummary summary;
  try {
    summary = session.Run(&std::cerr);
  } catch (...) {
    status.End();
    throw;
  }
  status.End();
  if (json) {
    std::cout << SummaryJson(summary).dump(2) << std::endl;
  } else {
    PrintSummary(summary, options.model_path, std::cout);
    std::cout << std::flush;
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
