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

struct ProbeSummary {
  int64_t frames = 0;
  TimestampNs first_ns = 0;
  TimestampNs last_ns = 0;
  bool timestamps_increasing = true;
  double valid_fraction_sum = 0.0;
  std::vector<uint16_t> depth_samples_mm;  // a subsample of valid depths, for the median
};

}  // namespace

int RunProbe(int argc, char** argv) {
  CLI::App app("Read a SOURCE to its end and report its streams, intrinsics and frame counts.",
               "sightmap probe");
  std::string source;
  bool json = false;
  int dump = 0;
  std::string out_dir;
  int64_t max_frames = -1;
  capture::SourceOptions options;
  app.add_option("SOURCE", source, "openni:// | openni://URI | FILE.oni | tum:DIR | 3dmatch:DIR")
      ->required();
  app.add_flag("--json", json, "print one JSON object (stable keys) instead of text");
  auto* dump_option =
      app.add_option("--dump", dump, "write the first N frames as PNG (3DMatch layout) to --out")
          ->check(Within(1, 1e9));
  auto* out_option = app.add_option("--out", out_dir, "folder for --dump (created if missing)");
  dump_option->needs(out_option);
  out_option->needs(dump_option);
  app.add_option("--max-frames", max_frames,
                 "stop after N frames (default: all of a recording, 30 from a live sensor)")
      ->check(Within(1, 1e12));
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
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;

  if (dump > 0) CheckOutputFolder(out_dir, "--out");

  std::unique_ptr<capture::RgbdSource> rgbd = capture::OpenSource(source, options);
  const capture::SourceMetadata& meta = rgbd->metadata();
  if (max_frames < 0 && meta.kind == "openni") max_frames = 30;
  if (dump > 0) capture::WriteThreeDMatchIntrinsics(out_dir, meta.intrinsics);

  // Progress on stderr for long folders, only when a person is watching.
  const bool show_progress = isatty(STDERR_FILENO) != 0;
  auto last_progress = std::chrono::steady_clock::now();

  ProbeSummary summary;
  while (max_frames < 0 || summary.frames < max_frames) {
    std::optional<RgbdFrame> frame = rgbd->Next();
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

  const capture::SourceStats stats = rgbd->stats();
  double median_mm = 0.0;
  if (!summary.depth_samples_mm.empty()) {
    auto mid = summary.depth_samples_mm.begin() + summary.depth_samples_mm.size() / 2;
    std::nth_element(summary.depth_samples_mm.begin(), mid, summary.depth_samples_mm.end());
    median_mm = *mid;
  }
  const double duration_s = summary.frames > 1 ? (summary.last_ns - summary.first_ns) * 1e-9 : 0.0;
  const double valid_fraction = summary.frames ? summary.valid_fraction_sum / summary.frames : 0.0;
  const Intrinsics& k = meta.intrinsics;

  if (json) {
    nlohmann::json out = {
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
        {"duration_s", duration_s},
        {"timestamps_increasing", summary.timestamps_increasing},
        {"depth_valid_fraction", valid_fraction},
        {"depth_median_mm", median_mm},
        {"has_ground_truth", meta.has_ground_truth},
        {"notes", meta.notes},
    };
    std::cout << out.dump(2) << std::endl;
    return kExitSuccess;
  }

  std::cout << std::fixed << std::setprecision(2);
  std::cout << "source        " << source << " (" << meta.kind << ")\n";
  if (!meta.device_name.empty()) {
    std::cout << "device        " << meta.device_name << (meta.vendor.empty() ? "" : ", ")
              << meta.vendor << (meta.serial.empty() ? "" : ", serial " + meta.serial) << "\n";
  }
  std::cout << "depth         " << stats.depth_frames << " frames, " << meta.depth_width << "x"
            << meta.depth_height << "\n";
  std::cout << "colour        " << stats.color_frames << " frames, " << meta.color_width << "x"
            << meta.color_height << "\n";
  std::cout << "rgbd frames   " << summary.frames << " at " << k.width << "x" << k.height
            << " (unpaired " << stats.unpaired_frames << "), " << duration_s << " s\n";
  if (stats.missed_depth_frames + stats.missed_color_frames > 0) {
    std::cout << "missed        " << stats.missed_depth_frames << " depth and "
              << stats.missed_color_frames << " colour frames (the reader fell behind)\n";
  }
  std::cout << "intrinsics    fx " << k.fx << "  fy " << k.fy << "  cx " << k.cx << "  cy " << k.cy
            << "  (" << meta.intrinsics_origin << ")\n";
  std::cout << "registration  " << ToString(meta.registration) << "\n";
  std::cout << "depth         " << std::setprecision(0) << valid_fraction * 100.0
            << "% valid, median " << median_mm << " mm\n";
  std::cout << "ground truth  " << (meta.has_ground_truth ? "yes" : "no") << "\n";
  for (const std::string& note : meta.notes) std::cout << "note          " << note << "\n";
  if (dump > 0) {
    std::cout << "dumped        " << std::min<int64_t>(dump, summary.frames) << " frames to "
              << out_dir << " (replay with 3dmatch:" << out_dir << ")\n";
  }
  if (!summary.timestamps_increasing) {
    std::cout << "warning       timestamps do not increase: the source's clock jumped\n";
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
