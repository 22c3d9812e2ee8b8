// Off-screen progress images: a thread with its own OSMesa context renders the map (floor plan and
// follow view, status overlay) every N keyframes and at the end, and rewrites one PNG atomically.
//
// Threading: the constructor starts the thread, which creates the OSMesa context (contexts belong
// to the thread that made them current) and the MapRenderer. Submit() merges the update into a
// mailbox and returns at once; the thread takes everything pending, applies it and renders if a
// multiple of N keyframes was reached since its last render. While it renders, new updates pile
// up and merge, so milestones passed meanwhile share one render ("a slow frame is skipped"),
// counted in stats().renders_skipped. The mapper never waits for a render.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "render/map_renderer.h"
#include "render/map_view.h"

namespace sightmap::render {

struct ProgressWriterOptions {
  std::string png_path;        // rewritten atomically (PATH.tmp, then rename); empty = no file
  int every_n_keyframes = 10;  // render when the keyframe count reaches a multiple of this (>= 1)
  // ... but not sooner than this after the previous render [s] (Finish always renders): a glance
  // every few seconds is all a progress image is for, and on two cores each render takes CPU
  // from mapping (measured: 14% fewer keyframes/s rendering every 10 keyframes at 20 kf/s).
  double min_interval_s = 3.0;
  // The thread's nice value is raised by this much (Linux, per thread; llvmpipe's rasteriser
  // threads, started from it, inherit it), so rendering yields the CPU to mapping.
  int nice_increment = 10;
  MapRenderOptions render;                              // image size, point size, views
  Eigen::Vector3d world_up = Eigen::Vector3d::UnitZ();  // see map_scene.h

  bool Check(std::string* error) const;
};

struct ProgressWriterStats {
  int64_t keyframes = 0;        // distinct keyframes in the writer's scene
  int64_t renders = 0;          // images rendered
  int64_t renders_skipped = 0;  // N-keyframe milestones folded into a later render
  int64_t pngs_written = 0;
  int64_t write_failures = 0;
  double last_render_ms = 0.0;  // GL drawing and read-back of the last image
  double last_write_ms = 0.0;   // PNG encoding and the atomic write
  std::string gl_renderer;      // e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string last_error;       // empty unless drawing or writing failed (never thrown at Submit)
};

class ProgressWriter : public MapView {
 public:
  // Throws InvalidArgument on bad options. GL failures on the thread are reported in stats().
  explicit ProgressWriter(const ProgressWriterOptions& options);
  // Finish()es (renders the final image) if that was not done, then joins the thread.
  ~ProgressWriter() override;
  ProgressWriter(const ProgressWriter&) = delete;
  ProgressWriter& operator=(const ProgressWriter&) = delete;

  void Submit(MapUpdate update) override;
  // Renders the final image and writes it, then stops the thread. Idempotent.
  void Finish() override;
  std::string description() const override;

  // Blocks until everything submitted so far is applied and its due render written (tests).
  void Flush();
  ProgressWriterStats stats() const;
  const ProgressWriterOptions& options() const { return options_; }

 private:
  void Run();
  void RenderAndWrite(class MapRenderer* renderer, const MapScene& scene);

  ProgressWriterOptions options_;
  MapMailbox mailbox_;
  std::atomic<bool> finish_requested_{false};
  mutable std::mutex stats_mutex_;
  ProgressWriterStats stats_;
  std::thread thread_;
};

}  // namespace sightmap::render
