// Figures for the model store, run by hand (not a ctest test):
//   store_benchmark [--keyframes N] [--large N] [--dir DIR] [--png-compression 0-9]
// 1. writes N 640x480 keyframes with 1,000 features each (real 3DMatch frames when the shared data
//    is present, else synthetic ones) and prints keyframes/s and bytes per keyframe;
// 2. builds a model of `--large` small keyframes and prints the time to open it, list its
//    keyframes, summarise it and update every pose in one transaction.

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "core/peak_memory.h"
#include "core/timing.h"
#include "store/model.h"
#include "store/synthetic_model.h"

namespace sightmap::store {
namespace {

using Clock = std::chrono::steady_clock;

int64_t FileBytes(const std::string& path) {
  std::error_code ec;
  int64_t total = 0;
  for (const std::string& file : {path, path + "-wal"}) {
    const auto size = std::filesystem::file_size(file, ec);
    if (!ec) total += static_cast<int64_t>(size);
  }
  return total;
}

// Real Kinect-class frames make JPEG sizes honest; synthetic texture compresses differently.
std::vector<std::pair<cv::Mat, cv::Mat>> LoadLoungeFrames() {
  std::vector<std::pair<cv::Mat, cv::Mat>> frames;
  const std::string dir = std::string(SIGHTMAP_SHARED_DATA_DIR) + "/rgbd/3dmatch-lounge/seq-01";
  for (const char* index : {"000000", "000001", "000002", "000116", "000422"}) {
    const std::string base = dir + "/frame-" + index;
    cv::Mat color = cv::imread(base + ".color.png", cv::IMREAD_COLOR);
    cv::Mat depth = cv::imread(base + ".depth.png", cv::IMREAD_UNCHANGED);
    if (color.empty() || depth.type() != CV_16UC1 || color.size() != depth.size()) return {};
    frames.emplace_back(color, depth);
  }
  return frames;
}

void WriteThroughput(const std::string& dir, int count, bool sync_every_commit,
                     int png_compression) {
  const std::string path = dir + (sync_every_commit ? "/write_sync.db" : "/write_nosync.db");
  std::filesystem::remove(path);
  const std::vector<std::pair<cv::Mat, cv::Mat>> lounge = LoadLoungeFrames();
  SyntheticKeyframeOptions options;  // 640x480, 1,000 features
  std::vector<KeyframeRecord> keyframes;
  for (int i = 0; i < 5; ++i) {
    keyframes.push_back(MakeSyntheticKeyframe(SessionId(1), i, options));
    if (!lounge.empty()) {
      keyframes.back().color = lounge[static_cast<size_t>(i)].first;
      keyframes.back().depth = lounge[static_cast<size_t>(i)].second;
    }
  }
  ModelOptions model_options;
  model_options.sync_every_commit = sync_every_commit;
  if (png_compression >= 0) model_options.png_compression = png_compression;
  const auto start = Clock::now();
  {
    Model model = Model::Open(path, model_options);
    const SessionId session = model.BeginSession({});
    KeyframeId previous;
    for (int i = 0; i < count; ++i) {
      KeyframeRecord& keyframe = keyframes[static_cast<size_t>(i % 5)];
      keyframe.session = session;
      keyframe.timestamp_ns = int64_t{i} * 1000000000;
      keyframe.links.clear();
      if (previous.valid()) {
        LinkRecord odometry;
        odometry.from = previous;
        keyframe.links.push_back(odometry);
      }
      previous = model.AddKeyframe(keyframe);
    }
  }  // closing checkpoints the WAL into the database file
  const double seconds = SecondsSince(start);
  int64_t color_bytes = 0;
  int64_t depth_bytes = 0;
  for (const KeyframeInfo& info : Model::Open(path).Keyframes()) {
    color_bytes += info.color_bytes;
    depth_bytes += info.depth_bytes;
  }
  std::printf("write %d x 640x480 keyframes, 1000 features, JPEG 90, %s images, %s:\n", count,
              lounge.empty() ? "synthetic" : "3DMatch lounge",
              sync_every_commit ? "fsync every commit (default)" : "no fsync per commit");
  std::printf("  %.1f keyframes/s (%.1f ms each, target >= 50/s)\n", count / seconds,
              1e3 * seconds / count);
  std::printf("  %.1f KB per keyframe on disk (target <= 250 KB)\n",
              FileBytes(path) / 1024.0 / count);
  std::printf("  of which colour JPEG %.1f KB, depth PNG %.1f KB, features %.1f KB\n",
              color_bytes / 1024.0 / count, depth_bytes / 1024.0 / count,
              1000 * (28 + 32 + 12) / 1024.0);
}

void LargeModel(const std::string& dir, int count) {
  const std::string path = dir + "/large.db";
  std::filesystem::remove(path);
  SyntheticKeyframeOptions small;
  small.width = 64;
  small.height = 48;
  small.num_features = 100;
  KeyframeRecord keyframe = MakeSyntheticKeyframe(SessionId(1), 0, small);
  ModelOptions fast;
  fast.sync_every_commit = false;
  auto start = Clock::now();
  {
    Model model = Model::Open(path, fast);
    keyframe.session = model.BeginSession({});
    KeyframeId previous;
    for (int i = 0; i < count; ++i) {
      keyframe.world_from_cam.translation().x() = 0.01 * i;
      keyframe.links.clear();
      if (previous.valid()) {
        LinkRecord odometry;
        odometry.from = previous;
        keyframe.links.push_back(odometry);
      }
      previous = model.AddKeyframe(keyframe);
    }
  }
  std::printf("large model: %d keyframes (64x48, 100 features) built in %.1f s, %.1f MB\n", count,
              SecondsSince(start), FileBytes(path) / 1e6);

  start = Clock::now();
  Model model = Model::Open(path);
  const double open_s = SecondsSince(start);
  start = Clock::now();
  const std::vector<KeyframeInfo> keyframes = model.Keyframes();
  const double list_s = SecondsSince(start);
  start = Clock::now();
  const ModelSummary summary = model.Summary();
  const double summary_s = SecondsSince(start);
  std::vector<std::pair<KeyframeId, Eigen::Isometry3d>> poses;
  for (const KeyframeInfo& info : keyframes) poses.emplace_back(info.id, info.world_from_cam);
  start = Clock::now();
  model.UpdatePoses(poses);
  const double update_s = SecondsSince(start);
  start = Clock::now();
  const cv::Mat color = model.LoadColor(keyframes[keyframes.size() / 2].id);
  const double load_s = SecondsSince(start);
  std::printf("  open %.1f ms + list %zu keyframes %.1f ms = %.1f ms (target < 1000 ms)\n",
              1e3 * open_s, keyframes.size(), 1e3 * list_s, 1e3 * (open_s + list_s));
  std::printf(
      "  summary (%lld segments) %.1f ms; update all poses in one transaction %.1f ms; "
      "load one colour image %.2f ms (%dx%d)\n",
      static_cast<long long>(summary.segments), 1e3 * summary_s, 1e3 * update_s, 1e3 * load_s,
      color.cols, color.rows);
}

}  // namespace
}  // namespace sightmap::store

int main(int argc, char** argv) {
  int count = 200;
  int png_compression = -1;
  int large = 10000;
  std::string dir = std::filesystem::temp_directory_path().string() + "/sightmap_store_benchmark";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--keyframes") count = std::atoi(argv[i + 1]);
    if (flag == "--large") large = std::atoi(argv[i + 1]);
    if (flag == "--dir") dir = argv[i + 1];
    if (flag == "--png-compression") png_compression = std::atoi(argv[i + 1]);
  }
  std::filesystem::create_directories(dir);
  try {
    sightmap::store::WriteThroughput(dir, count, true, png_compression);
    sightmap::store::WriteThroughput(dir, count, false, png_compression);
    sightmap::store::LargeModel(dir, large);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  std::printf("peak RSS %.0f MiB\n", sightmap::PeakRssMiB());
  return 0;
}
