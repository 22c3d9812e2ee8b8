#include "render/progress_writer.h"

#include <chrono>
#include <exception>

#include "core/check.h"
#include "core/thread_priority.h"
#include "render/image_file.h"
#include "render/offscreen_context.h"

namespace sightmap::render {

bool ProgressWriterOptions::Check(std::string* error) const {
  if (min_interval_s < 0.0 || nice_increment < 0 || nice_increment > 19) {
    *error = "min_interval_s must be >= 0 and nice_increment in [0, 19]";
    return false;
  }
  if (every_n_keyframes < 1) {
    *error = "every_n_keyframes must be at least 1";
    return false;
  }
  if (world_up.norm() < 0.5) {
    *error = "world_up must be a non-zero direction";
    return false;
  }
  return render.Check(error);
}

ProgressWriter::ProgressWriter(const ProgressWriterOptions& options) : options_(options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  thread_ = std::thread([this] { Run(); });
}

ProgressWriter::~ProgressWriter() {
  try {
    Finish();
  } catch (...) {
    // A destructor must not throw; Finish() only joins.
  }
}

void ProgressWriter::Submit(MapUpdate update) {
  if (finish_requested_.load()) return;  // nobody would take it
  mailbox_.Post(std::move(update));
}

void ProgressWriter::Finish() {
  if (!thread_.joinable()) return;
  finish_requested_ = true;
  mailbox_.Notify();
  thread_.join();
}

void ProgressWriter::Flush() { mailbox_.WaitDone(); }

std::string ProgressWriter::description() const {
  std::string text = options_.png_path.empty() ? std::string("off-screen rendering (no image file)")
                                               : "progress images (" + options_.png_path + ")";
  const ProgressWriterStats now = stats();
  if (now.write_failures > 0) {
    text += "; " + std::to_string(now.write_failures) + " failed, the last: " + now.last_error;
  }
  return text;
}

ProgressWriterStats ProgressWriter::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

void ProgressWriter::RenderAndWrite(MapRenderer* renderer, const MapScene& scene) {
  using Clock = std::chrono::steady_clock;
  const int width = options_.render.width;
  const int height = options_.render.height;
  const auto start = Clock::now();
  renderer->DrawProgress(scene, width, height);
  const cv::Mat image = renderer->ReadImage(width, height);
  const auto rendered = Clock::now();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.renders;
    stats_.last_render_ms = std::chrono::duration<double, std::milli>(rendered - start).count();
  }
  if (options_.png_path.empty()) return;
  try {
    WriteImageAtomically(options_.png_path, image);
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.pngs_written;
    stats_.last_write_ms =
        std::chrono::duration<double, std::milli>(Clock::now() - rendered).count();
  } catch (const std::exception& e) {
    // A full disk must not stop the mapping: keep going, report it.
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.write_failures;
    stats_.last_error = e.what();
  }
}

void ProgressWriter::Run() {
  // Best effort: a failure only means rendering competes at normal priority.
  (void)LowerThisThreadsPriority(options_.nice_increment);
  std::unique_ptr<OffscreenContext> context;
  std::unique_ptr<MapRenderer> renderer;
  try {
    context = std::make_unique<OffscreenContext>(options_.render.width, options_.render.height);
    renderer = std::make_unique<MapRenderer>(&OffscreenContext::ProcAddress, options_.render);
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.gl_renderer = context->GlRenderer();
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.last_error = e.what();
  }
  MapScene scene(options_.world_up);
  const int64_t n = options_.every_n_keyframes;
  int64_t rendered_milestone = 0;
  using Clock = std::chrono::steady_clock;
  Clock::time_point last_render = Clock::now() - std::chrono::hours(1);
  const auto min_interval = std::chrono::duration<double>(options_.min_interval_s);
  while (true) {
    // Read the flag first: whatever was submitted before Finish() is then in this Take.
    const bool finishing = finish_requested_.load();
    uint64_t covers = 0;
    MapUpdate update = mailbox_.Take([this] { return finish_requested_.load(); },
                                     std::chrono::seconds(1), &covers);
    try {
      scene.Apply(std::move(update));
      const int64_t keyframes = static_cast<int64_t>(scene.keyframes().size());
      const int64_t milestone = keyframes / n;
      {
        std::lock_guard<std::mutex> lock(stats_mutex_);
        stats_.keyframes = keyframes;
      }
      const bool due = milestone > rendered_milestone && Clock::now() - last_render >= min_interval;
      if (renderer && (due || finishing)) {
        if (milestone > rendered_milestone + 1) {
          std::lock_guard<std::mutex> lock(stats_mutex_);
          stats_.renders_skipped += milestone - rendered_milestone - 1;
        }
        rendered_milestone = milestone;
        RenderAndWrite(renderer.get(), scene);
        last_render = Clock::now();
      }
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      stats_.last_error = e.what();
    }
    mailbox_.MarkDone(covers);
    if (finishing) break;
  }
  renderer.reset();  // frees its buffers while the context is still current
  context.reset();
  mailbox_.MarkAllDone();
}

}  // namespace sightmap::render
