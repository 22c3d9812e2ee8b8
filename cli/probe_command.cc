// sightmap probe SOURCE [--json] [--dump N --out DIR]: reads a source to its end (a live sensor for
// --max-frames frames) and reports what it delivers. Scripts read the --json keys; they are stable.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/folder_source.h"
#include "capture/rgbd_source.h"
#include "cli/command_util.h"
#include "cli/commands.h"
#include "core/check.h"

namespace sightmap::cli {
namespace {

struct ProbeArgs {
  std::string source;
  bool json = false;
  int dump = 0;
  std::string out_dir;
  int64_t max_frames = -1;  // -1: all of a recording, 30 from a live sensor
  capture::SourceOptions options;
};

// What reading the source to its end found.
struct ProbeSummary {
  int64_t frames = 0;
  TimestampNs first_ns = 0;
  TimestampNs last_ns = 0;
  bool timestamps_increasing = true;
  double valid_fraction_sum = 0.0;
  std::vector<uint16_t> depth_samples_mm;  // a subsample of valid depths, for the median

  double DurationS() const { return frames > 1 ? (last_ns - first_ns) * 1e-9 : 0.0; }
  double ValidFraction() const { return frames ? valid_fraction_sum / frames : 0.0; }
  double MedianDepthMm() {
    if (depth_samples_mm.empty()) return 0.0;
    auto mid = depth_samples_mm.begin() + depth_samples_mm.size() / 2;
    std::nth_element(depth_samples_mm.begin(), mid, depth_samples_mm.end());
    return *mid;
  }
};

void DeclareProbe(CLI::App& app, ProbeArgs* args) {
  app.add_option("SOURCE", args->source,
                 "openni:// | openni://URI | FILE.oni | tum:DIR | 3dmatch:DIR")
      ->required();
  app.add_flag("--json", args->json, "print one JSON object (stable keys) instead of text");
  auto* dump_option = app.add_option("--dump", args->dump,
                                     "write the first N frames as PNG (3DMatch layout) to --out")
                          ->check(Within(1, 1e9));
  auto* out_option =
      app.add_option("--out", args->out_dir, "folder for --dump (created if missing)");
  dump_option->needs(out_option);
  out_option->needs(dump_option);
  app.add_option("--max-frames", args->max_frames,
                 "stop after N frames (default: all of a recording, 30 from a live sensor)")
      ->check(Within(1, 1e12));
  capture::SourceOptions& options = args->options;
  app.add_flag("--realtime", options.realtime, "replay a recording at its recorded pace");
  app.add_option("--calib", options.calibration_file,
                 "JSON calibration overriding intrinsics and depth-to-colour registration")
      ->check(CLI::ExistingFile);
  app.add_option("--width", options.width, "live sensor: image width [px]")
      ->check(Within(1, 10000, "px"))
      ->capture_default_str();
  app.add_option("--height", options.height, "live sensor: image height [px]")
      ->check(Within(1, 10000, "px"))
      ->capture_default_str();
  app.add_option("--fps", options.fps, "live sensor: frame rate [Hz]")
      ->check(Within(1, 120, "Hz"))
      ->capture_default_str();
}

// Reads up to `max_frames` frames (all when negative), dumping the first `dump` to `out_dir`;
// progress on stderr for long folders, only when a person is watching.
ProbeSummary ReadFrames(capture::RgbdSource& rgbd, int64_t max_frames, int dump,
                        const std::string& out_dir) {
  const capture::SourceMetadata& meta = rgbd.metadata();
  const bool show_progress = isatty(STDERR_FILENO) != 0;
  auto last_progress = std::chrono::steady_clock::now();
  ProbeSummary summary;
  while (max_frames < 0 || summary.frames < max_frames) {
    std::optional<RgbdFrame> frame = rgbd.Next();
    if (!frame) break;
    if (summary.frames == 0) summary.first_ns = frame->timestamp_ns;
    if (summary.frames > 0 && frame->timestamp_ns <= summary.last_ns) {
      summary.timestamps_increasing = false;
    }
    summary.last_ns = frame->timestamp_ns;
    summary.valid_fraction_sum += ValidDepthFraction(frame->depth);
    for (int v = 0; v < frame->depth.rows; v += 16) {
      for (int u = 0; u < frame->depth.cols; u += 16) {
        const uint16_t z = frame->depth.at<uint16_t>(v, u);
        if (z) summary.depth_samples_mm.push_back(z);
      }
    }
    if (summary.frames < dump) capture::WriteThreeDMatchFrame(out_dir, *frame);
    ++summary.frames;
    if (show_progress &&
        std::chrono::steady_clock::now() - last_progress > std::chrono::seconds(1)) {
      last_progress = std::chrono::steady_clock::now();
      std::cerr << "\rprobe: " << summary.frames << " frames";
      if (meta.depth_frame_count) std::cerr << " of " << *meta.depth_frame_count;
      std::cerr << std::flush;
    }
  }
  if (show_progress) std::cerr << "\r" << std::string(40, ' ') << "\r" << std::flush;
  return summary;
}

nlohmann::json ProbeJson(const std::string& source, const capture::SourceMetadata& meta,
                         const capture::SourceStats& stats, ProbeSummary& summary) {
  const Intrinsics& k = meta.intrinsics;
  return {
      {"source", source},
      {"kind", meta.kind},
      {"uri", meta.uri},
      {"device_name", meta.device_name},
      {"vendor", meta.vendor},
      {"serial", meta.serial},
      {"depth_frames", stats.depth_frames},
      {"color_frames", stats.color_frames},
      {"rgbd_frames", summary.frames},
      {"unpaired_frames", stats.unpaired_frames},
      {"missed_depth_frames", stats.missed_depth_frames},
      {"missed_color_frames", stats.missed_color_frames},
      {"depth_width", meta.depth_width},
      {"depth_height", meta.depth_height},
      {"color_width", meta.color_width},
      {"color_height", meta.color_height},
      {"frame_width", k.width},
      {"frame_height", k.height},
      {"fx", k.fx},
      {"fy", k.fy},
      {"cx", k.cx},
      {"cy", k.cy},
      {"intrinsics_origin", meta.intrinsics_origin},
      {"registration", ToString(meta.registration)},
      {"depth_resized_to_color", meta.depth_resized_to_color},
      {"mirrored_in_software", meta.mirrored_in_software},
      {"nominal_fps", meta.nominal_fps},
      {"duration_s", summary.DurationS()},
      {"timestamps_increasing", summary.timestamps_increasing},
      {"depth_valid_fraction", summary.ValidFraction()},
      {"depth_median_mm", summary.MedianDepthMm()},
      {"has_ground_truth", meta.has_ground_truth},
      {"notes", meta.notes},
  };
}

void PrintProbe(const ProbeArgs& args, const capture::SourceMetadata& meta,
                const capture::SourceStats& stats, ProbeSummary& summary) {
  const Intrinsics& k = meta.intrinsics;
  std::cout << std::fixed << std::setprecision(2);
  std::cout << "source        " << args.source << " (" << meta.kind << ")\n";
  if (!meta.device_name.empty()) {
    std::cout << "device        " << meta.device_name << (meta.vendor.empty() ? "" : ", ")
              << meta.vendor << (meta.serial.empty() ? "" : ", serial " + meta.serial) << "\n";
  }
  std::cout << "depth         " << stats.depth_frames << " frames, " << meta.depth_width << "x"
            << meta.depth_height << "\n";
  std::cout << "colour        " << stats.color_frames << " frames, " << meta.color_width << "x"
            << meta.color_height << "\n";
  std::cout << "rgbd frames   " << summary.frames << " at " << k.width << "x" << k.height
            << " (unpaired " << stats.unpaired_frames << "), " << summary.DurationS() << " s\n";
  if (stats.missed_depth_frames + stats.missed_color_frames > 0) {
    std::cout << "missed        " << stats.missed_depth_frames << " depth and "
              << stats.missed_color_frames << " colour frames (the reader fell behind)\n";
  }
  std::cout << "intrinsics    fx " << k.fx << "  fy " << k.fy << "  cx " << k.cx << "  cy " << k.cy
            << "  (" << meta.intrinsics_origin << ")\n";
  std::cout << "registration  " << ToString(meta.registration) << "\n";
  std::cout << "depth         " << std::setprecision(0) << summary.ValidFraction() * 100.0
            << "% valid, median " << summary.MedianDepthMm() << " mm\n";
  std::cout << "ground truth  " << (meta.has_ground_truth ? "yes" : "no") << "\n";
  for (const std::string& note : meta.notes) std::cout << "note          " << note << "\n";
  if (args.dump > 0) {
    std::cout << "dumped        " << std::min<int64_t>(args.dump, summary.frames) << " frames to "
              << args.out_dir << " (replay with 3dmatch:" << args.out_dir << ")\n";
  }
  if (!summary.timestamps_increasing) {
    std::cout << "warning       timestamps do not increase: the source's clock jumped\n";
  }
}

}  // namespace

int RunProbe(int argc, char** argv) {
  CLI::App app("Read a SOURCE to its end and report its streams, intrinsics and frame counts.",
               "sightmap probe");
  ProbeArgs args;
  DeclareProbe(app, &args);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;

  if (args.dump > 0) CheckOutputFolder(args.out_dir, "--out");
  std::unique_ptr<capture::RgbdSource> rgbd = capture::OpenSource(args.source, args.options);
  const capture::SourceMetadata& meta = rgbd->metadata();
  const int64_t max_frames = args.max_frames < 0 && meta.kind == "openni" ? 30 : args.max_frames;
  if (args.dump > 0) capture::WriteThreeDMatchIntrinsics(args.out_dir, meta.intrinsics);
  ProbeSummary summary = ReadFrames(*rgbd, max_frames, args.dump, args.out_dir);
  const capture::SourceStats stats = rgbd->stats();
  if (args.json) {
    std::cout << ProbeJson(args.source, meta, stats, summary).dump(2) << std::endl;
  } else {
    PrintProbe(args, meta, stats, summary);
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
