#include "render/progress_writer.h"

#include <atomic>
#include <chrono>
#include <filesystem>
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "tests/test_data.h"

namespace sightmap::render {
namespace {

std::string TempPath(const std::string& name) {
  return sightmap::testing::MakeTempDir("progress") + "/" + name;
}

MapKeyframe RandomKeyframe(int64_t id, int points, std::mt19937* rng) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  MapKeyframe keyframe;
  keyframe.id = id;
  keyframe.world_from_cam.translation() = Eigen::Vector3d(0.05 * id, std::sin(0.1 * id), 1.4);
  for (int i = 0; i < points; ++i) {
    keyframe.points_cam.emplace_back(unit(*rng) - 0.5f, unit(*rng) - 0.5f, 1.0f + unit(*rng));
    keyframe.colors.push_back({200, static_cast<uint8_t>(unit(*rng) * 255), 50});
  }
  return keyframe;
}

ProgressWriterOptions SmallOptions(const std::string& path, int every_n) {
  ProgressWriterOptions options;
  options.png_path = path;
  options.every_n_keyframes = every_n;
  options.min_interval_s = 0.0;  // renders counted exactly; the interval has a test of its own
  options.render.width = 320;
  options.render.height = 180;
  return options;
}

// A render every N keyframes and one at the end, each PNG complete whenever a reader looks.
TEST(ProgressWriter, WritesAtomicPngsEveryNKeyframesAndAtTheEnd) {
  const std::string path = TempPath("every_n.png");
  std::filesystem::remove(path);
  std::atomic<bool> stop_reader{false};
  std::atomic<int> reads{0};
  std::atomic<int> bad_reads{0};
  // A viewer polling the file: it must never see a partial PNG.
  std::thread reader([&] {
    while (!stop_reader) {
      if (std::filesystem::exists(path)) {
        const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
        ++reads;
        if (image.cols != 320 || image.rows != 180) ++bad_reads;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });
  ProgressWriter writer(SmallOptions(path, 5));
  std::mt19937 rng(1);
  for (int64_t i = 1; i <= 15; ++i) {
    MapUpdate update;
    update.keyframes.push_back(RandomKeyframe(i, 500, &rng));
    writer.Submit(std::move(update));
    writer.Flush();  // the writer keeps up, so every milestone gets its own render
    EXPECT_EQ(writer.stats().renders, i / 5) << "after keyframe " << i;
  }
  writer.Finish();
  stop_reader = true;
  reader.join();
  const ProgressWriterStats stats = writer.stats();
  EXPECT_EQ(stats.renders, 4);  // keyframes 5, 10, 15 and the end
  EXPECT_EQ(stats.pngs_written, 4);
  EXPECT_EQ(stats.renders_skipped, 0);
  EXPECT_EQ(stats.keyframes, 15);
  EXPECT_TRUE(stats.last_error.empty()) << stats.last_error;
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_EQ(image.cols, 320);
  ASSERT_EQ(image.rows, 180);
  EXPECT_GT(reads.load(), 0);
  EXPECT_EQ(bad_reads.load(), 0);
}

// Milestones closer together than min_interval_s share one render; the end always renders.
TEST(ProgressWriter, RendersNoMoreOftenThanTheMinimumInterval) {
  const std::string path = TempPath("interval.png");
  ProgressWriterOptions options = SmallOptions(path, 5);
  options.min_interval_s = 60.0;
  ProgressWriter writer(options);
  std::mt19937 rng(3);
  for (int64_t i = 1; i <= 15; ++i) {
    MapUpdate update;
    update.keyframes.push_back(RandomKeyframe(i, 500, &rng));
    writer.Submit(std::move(update));
    writer.Flush();
  }
  EXPECT_EQ(writer.stats().renders, 1);  // keyframe 5; 10 and 15 fall within the minute
  writer.Finish();
  EXPECT_EQ(writer.stats().renders, 2);
  EXPECT_EQ(writer.stats().keyframes, 15);
}

// 1,000 keyframes submitted as fast as possible: Submit never waits for a render, milestones the
// writer cannot keep up with are folded into later renders, and the final image has them all.
TEST(ProgressWriter, ProducerNeverBlocksAndSlowRendersAreSkipped) {
  const std::string path = TempPath("fast.png");
  ProgressWriterOptions options = SmallOptions(path, 10);
  options.render.width = 640;
  options.render.height = 360;
  std::mt19937 rng(2);
  std::vector<MapKeyframe> keyframes;
  for (int64_t i = 0; i < 1000; ++i) keyframes.push_back(RandomKeyframe(i, 2000, &rng));

  using Clock = std::chrono::steady_clock;
  ProgressWriter writer(options);
  double slowest_submit_ms = 0.0;
  const auto start = Clock::now();
  for (MapKeyframe& keyframe : keyframes) {
    const auto before = Clock::now();
    MapUpdate update;
    update.camera = keyframe.world_from_cam;
    update.keyframes.push_back(std::move(keyframe));
    update.status = MapStatus{update.keyframes[0].id + 1, 0, TrackingState::kTracking, 30.0, 1.0};
    writer.Submit(std::move(update));
    slowest_submit_ms =
        std::max(slowest_submit_ms,
                 std::chrono::duration<double, std::milli>(Clock::now() - before).count());
  }
  const double feed_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  const auto finish_start = Clock::now();
  writer.Finish();
  const double finish_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - finish_start).count();
  const ProgressWriterStats stats = writer.stats();
  std::printf(
      "fed 1000 keyframes in %.1f ms (slowest Submit %.2f ms); %lld renders, %lld "
      "skipped, last render %.1f ms; Finish %.0f ms\n",
      feed_ms, slowest_submit_ms, static_cast<long long>(stats.renders),
      static_cast<long long>(stats.renders_skipped), stats.last_render_ms, finish_ms);
  // Against the renderer's own time in this run, not a wall-clock budget: a Submit that waited
  // for renders would take at least one render per milestone (100 of them) to feed everything;
  // a busy machine slows both sides alike.
  ASSERT_GT(stats.last_render_ms, 0.0);
  EXPECT_LT(feed_ms, 10.0 * stats.last_render_ms)
      << "feeding 1,000 keyframes took as long as " << feed_ms / stats.last_render_ms
      << " renders: Submit waits for the renderer";
  EXPECT_EQ(stats.keyframes, 1000);
  EXPECT_GT(stats.renders_skipped, 0);
  // Every milestone is rendered or skipped, plus possibly the final render.
  EXPECT_GE(stats.renders + stats.renders_skipped, 100);
  EXPECT_LE(stats.renders + stats.renders_skipped, 101);
  EXPECT_GE(stats.pngs_written, 1);
  // A hang guard, not a timing target: Finish renders once more and joins.
  EXPECT_LT(finish_ms, 60000.0);
  const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  EXPECT_EQ(image.cols, 640);
}

TEST(ProgressWriter, AnUnwritableFileIsReportedNotThrown) {
  ProgressWriter writer(SmallOptions("/nonexistent-dir/progress.png", 1));
  MapUpdate update;
  std::mt19937 rng(3);
  update.keyframes.push_back(RandomKeyframe(1, 10, &rng));
  writer.Submit(std::move(update));
  writer.Finish();
  const ProgressWriterStats stats = writer.stats();
  EXPECT_GE(stats.renders, 1);
  EXPECT_EQ(stats.pngs_written, 0);
  EXPECT_GE(stats.write_failures, 1);
  EXPECT_NE(stats.last_error.find("/nonexistent-dir/progress.png"), std::string::npos);
  // The summary `map` prints names the failure too.
  EXPECT_NE(writer.description().find("failed, the last: "), std::string::npos)
      << writer.description();
}

}  // namespace
}  // namespace sightmap::render
