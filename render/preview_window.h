// The live preview: a GLFW window, on its own thread, with the 3D map (mouse orbit, pan, zoom),
// the live colour and depth images, the floor plan and the status overlay.
//
// Keys: space pauses capture (paused(), polled by the mapper), `s` saves a snapshot PNG (written
// atomically into PreviewOptions::snapshot_dir), `q` or closing the window asks the mapper to stop
// (stop_requested(); the mapper saves the model and returns). Mouse: left drag orbits, right (or
// middle, or shift + left) drag pans, the wheel zooms; `f` follows the camera again after a pan.
//
// Threading: every GLFW call and the GL context live on the window thread (GLFW asks for the main
// thread; on X11 one dedicated thread works as long as no other thread calls GLFW, so at most one
// PreviewWindow exists at a time). Submit() and SetLiveImages() hand data over without waiting;
// the window draws at most max_fps frames per second with whatever arrived last.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "render/map_renderer.h"
#include "render/map_view.h"

namespace sightmap::render {

struct PreviewOptions {
  int width = 1280;  // window size [screen px]
  int height = 720;
  std::string title = "sightmap";
  std::string snapshot_dir = ".";  // `s` writes sightmap-snapshot-NNNN.png here
  double max_fps = 30.0;
  bool visible = true;  // false: a hidden window (tests)
  MapRenderOptions render;
  Eigen::Vector3d world_up = Eigen::Vector3d::UnitZ();  // see map_scene.h

  bool Check(std::string* error) const;
};

class PreviewWindow : public MapView {
 public:
  // Opens the window (waits until it is open). Throws sightmap::Error with GLFW's reason when it
  // cannot (no display, no GLX, another PreviewWindow open).
  explicit PreviewWindow(const PreviewOptions& options);
  // Closes the window and joins its thread.
  ~PreviewWindow() override;
  PreviewWindow(const PreviewWindow&) = delete;
  PreviewWindow& operator=(const PreviewWindow&) = delete;

  void Submit(MapUpdate update) override;
  void SetLiveImages(const cv::Mat& bgr, const cv::Mat& depth_mm) override;
  bool paused() const override;
  bool stop_requested() const override;
  // Waits until everything submitted is drawn (the window stays open until destruction).
  void Finish() override;
  std::string description() const override;

  // The next frame as drawn, BGR, framebuffer size; empty if none comes within `timeout`.
  cv::Mat Screenshot(std::chrono::milliseconds timeout = std::chrono::seconds(10));
  // Input as if from the user, handled on the window thread like real events (tests, scripts):
  // a key (' ', 's', 'q', 'f'), a drag with button 0 = left, 1 = right by (dx, dy) pixels, a
  // wheel turn.
  void InjectKey(char key);
  void InjectDrag(int button, double dx, double dy);
  void InjectScroll(double dy);
  // Frames drawn and snapshots written so far; the last snapshot's path.
  int64_t frames_drawn() const;
  int64_t snapshots_written() const;
  std::string last_snapshot() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::render
