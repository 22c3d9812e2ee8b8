#include "render/preview_window.h"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "render/image_file.h"

namespace sightmap::render {
namespace {

// GLFW reports errors through a process-wide callback; keep the last message for the exception.
std::mutex g_glfw_error_mutex;
std::string g_glfw_error;
void OnGlfwError(int code, const char* description) {
  std::lock_guard<std::mutex> lock(g_glfw_error_mutex);
  g_glfw_error = std::string(description) + " (GLFW error " + std::to_string(code) + ")";
}
std::string LastGlfwError() {
  std::lock_guard<std::mutex> lock(g_glfw_error_mutex);
  return g_glfw_error.empty() ? std::string("unknown GLFW error") : g_glfw_error;
}

// At most one window: GLFW is process-wide and lives on one thread.
std::atomic<bool> g_window_open{false};

cv::Mat ColorizeDepth(const cv::Mat& depth_mm) {
  cv::Mat scaled;
  depth_mm.convertTo(scaled, CV_8U, 255.0 / 5000.0);  // 0-5 m
  cv::Mat colored;
  cv::applyColorMap(scaled, colored, cv::COLORMAP_JET);
  colored.setTo(cv::Scalar(0, 0, 0), depth_mm == 0);
  return colored;
}

}  // namespace

bool PreviewOptions::Check(std::string* error) const {
  if (width < 64 || height < 64) {
    *error = "the preview window must be at least 64x64";
    return false;
  }
  if (!(max_fps > 0.0)) {
    *error = "max_fps must be positive";
    return false;
  }
  return render.Check(error);
}

struct PreviewWindow::Impl {
  PreviewOptions options;
  MapMailbox mailbox;
  std::thread thread;
  std::atomic<bool> quit{false};
  std::atomic<bool> paused{false};
  std::atomic<bool> stop_requested{false};
  std::atomic<int64_t> frames{0};
  std::atomic<int64_t> snapshots{0};

  std::mutex mutex;  // guards the fields below
  cv::Mat live_bgr;
  cv::Mat live_depth;
  bool images_changed = false;
  std::vector<std::function<void()>> commands;
  std::vector<std::promise<cv::Mat>> screenshot_requests;
  std::string last_snapshot;

  // Window-thread state.
  GLFWwindow* window = nullptr;
  std::unique_ptr<MapRenderer> renderer;
  MapScene scene;
  cv::Mat shown_bgr;
  cv::Mat shown_depth;
  double yaw = -kPi / 2;  // orbit view [rad]
  double pitch = DegToRad(50.0);
  double distance = 9.0;  // [m]
  bool follow = true;     // the orbit centre follows the camera until the user pans
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  bool dragging[2] = {false, false};
  double last_x = 0.0;
  double last_y = 0.0;
  bool snapshot_pending = false;

  explicit Impl(const PreviewOptions& preview_options)
      : options(preview_options), scene(preview_options.world_up) {}

  void HandleKey(char key) {
    switch (key) {
      case ' ':
        paused = !paused;
        break;
      case 's':
        snapshot_pending = true;
        break;
      case 'q':
        stop_requested = true;
        break;
      case 'f':
        follow = true;
        break;
      default:
        break;
    }
  }

  void HandleDrag(int button, double dx, double dy) {
    if (button == 0) {
      yaw -= dx * 0.01;
      pitch = std::clamp(pitch + dy * 0.01, DegToRad(-85.0), DegToRad(89.0));
    } else {
      // Pan in the view's image plane, scaled so the map follows the cursor at the target.
      int fb_width = 1, fb_height = 1;
      glfwGetFramebufferSize(window, &fb_width, &fb_height);
      const ViewCamera view =
          OrbitView(std::max(1, MainViewport(fb_width, fb_height).width), std::max(1, fb_height));
      const double metres_per_px = distance / view.intrinsics.fx;
      target -= view.world_from_cam.linear() * Eigen::Vector3d(dx, dy, 0) * metres_per_px;
      follow = false;
    }
  }

  void HandleScroll(double dy) { distance = std::clamp(distance * std::pow(0.85, dy), 0.3, 500.0); }

  static Viewport MainViewport(int width, int height) { return {0, 0, width * 2 / 3, height}; }

  ViewCamera OrbitView(int width, int height) const {
    return OrbitCamera(target, yaw, pitch, distance, scene.world_up(), width, height, 60.0);
  }

  // `requests` were taken together with the commands run before this frame, so a screenshot asked
  // for after an injected input shows its effect.
  void DrawFrame(std::vector<std::promise<cv::Mat>>& requests) {
    int width = 0, height = 0;
    glfwGetFramebufferSize(window, &width, &height);
    if (width <= 0 || height <= 0) return;  // minimised
    if (follow) {
      if (scene.camera()) {
        target = scene.camera()->translation();
      } else if (!scene.keyframes().empty()) {
        target = scene.keyframes().rbegin()->second.world_from_cam.translation();
      }
    }
    MapRenderer& r = *renderer;
    r.Sync(scene);
    r.BeginFrame(width, height);
    const Viewport main = MainViewport(width, height);
    r.DrawMap(scene, OrbitView(main.width, main.height), main);
    const int side_x = main.width;
    const int side_w = width - main.width;
    const int third = height / 3;
    const Viewport color_vp{side_x, 0, side_w, third};
    const Viewport depth_vp{side_x, third, side_w, third};
    const Viewport plan_vp{side_x, 2 * third, side_w, height - 2 * third};
    r.DrawImage(shown_bgr, color_vp);
    r.DrawImage(shown_depth, depth_vp);
    r.DrawMap(scene, TopDownCamera(scene, plan_vp.width, plan_vp.height, r.options()), plan_vp);
    r.DrawStatus(scene, main);
    const int scale = r.options().text_scale;
    const Eigen::Vector3f grey(0.8f, 0.8f, 0.85f);
    r.DrawText("colour", side_x + 4 * scale, 4 * scale, scale, grey);
    r.DrawText("depth", side_x + 4 * scale, third + 4 * scale, scale, grey);
    r.DrawText("floor plan", side_x + 4 * scale, 2 * third + 4 * scale, scale, grey);
    r.DrawText(
        "drag: orbit  right-drag: pan  wheel: zoom  f: follow  space: pause  s: snapshot  "
        "q: quit",
        4 * scale, height - 11 * scale, std::max(1, scale / 2 + scale % 2), grey);
    if (paused) {
      r.DrawText("PAUSED", main.width / 2 - 18 * scale * 2, height / 2, 2 * scale,
                 Eigen::Vector3f(1.0f, 0.85f, 0.2f));
    }
    if (stop_requested) {
      r.DrawText("stopping: saving the model", 4 * scale, height - 24 * scale, scale,
                 Eigen::Vector3f(1.0f, 0.4f, 0.3f));
    }
    if (!requests.empty() || snapshot_pending) {
      const cv::Mat image = r.ReadImage(width, height);
      for (auto& request : requests) request.set_value(image.clone());
      requests.clear();
      if (snapshot_pending) {
        snapshot_pending = false;
        char name[64];
        std::snprintf(name, sizeof(name), "/sightmap-snapshot-%04lld.png",
                      static_cast<long long>(snapshots.load() + 1));
        const std::string path = options.snapshot_dir + name;
        try {
          WriteImageAtomically(path, image);
          ++snapshots;
          std::lock_guard<std::mutex> lock(mutex);
          last_snapshot = path;
        } catch (const Error& e) {
          std::fprintf(stderr, "sightmap: snapshot failed: %s\n", e.what());
        }
      }
    }
    glfwSwapBuffers(window);
    ++frames;
  }

  void Loop() {
    using Clock = std::chrono::steady_clock;
    const auto frame_time = std::chrono::duration<double>(1.0 / options.max_fps);
    while (!quit) {
      const auto start = Clock::now();
      glfwPollEvents();
      if (glfwWindowShouldClose(window)) {
        stop_requested = true;
        glfwSetWindowShouldClose(window, GLFW_FALSE);
      }
      std::vector<std::function<void()>> pending_commands;
      std::vector<std::promise<cv::Mat>> requests;
      {
        std::lock_guard<std::mutex> lock(mutex);
        pending_commands.swap(commands);
        requests.swap(screenshot_requests);
        if (images_changed) {
          images_changed = false;
          shown_bgr = live_bgr;
          if (!live_depth.empty()) shown_depth = ColorizeDepth(live_depth);
        }
      }
      for (auto& command : pending_commands) command();
      uint64_t covers = 0;
      MapUpdate update = mailbox.Take([] { return true; }, std::chrono::milliseconds(0), &covers);
      try {
        scene.Apply(std::move(update));
        DrawFrame(requests);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "sightmap: preview frame failed: %s\n", e.what());
      }
      for (auto& request : requests) request.set_value(cv::Mat());  // frame failed
      mailbox.MarkDone(covers);
      std::this_thread::sleep_until(start +
                                    std::chrono::duration_cast<Clock::duration>(frame_time));
    }
  }

  // Window thread: open, report through `opened`, draw until quit, close.
  void Run(std::promise<std::string>* opened) {
    glfwSetErrorCallback(&OnGlfwError);
    if (glfwInit() != GLFW_TRUE) {
      opened->set_value("GLFW could not start: " + LastGlfwError());
      return;
    }
    glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    window =
        glfwCreateWindow(options.width, options.height, options.title.c_str(), nullptr, nullptr);
    if (window == nullptr) {
      opened->set_value("GLFW could not open a window: " + LastGlfwError());
      glfwTerminate();
      return;
    }
    glfwMakeContextCurrent(window);
    glfwSwapInterval(0);  // the loop paces itself; a blocked swap would stall event handling
    try {
      renderer = std::make_unique<MapRenderer>(&glfwGetProcAddress, options.render);
    } catch (const std::exception& e) {
      opened->set_value(std::string("the window's OpenGL is not usable: ") + e.what());
      glfwDestroyWindow(window);
      glfwTerminate();
      return;
    }
    glfwSetWindowUserPointer(window, this);
    glfwSetKeyCallback(window, [](GLFWwindow* w, int key, int, int action, int) {
      if (action != GLFW_PRESS) return;
      auto* self = static_cast<Impl*>(glfwGetWindowUserPointer(w));
      if (key == GLFW_KEY_SPACE) self->HandleKey(' ');
      if (key == GLFW_KEY_S) self->HandleKey('s');
      if (key == GLFW_KEY_Q) self->HandleKey('q');
      if (key == GLFW_KEY_F) self->HandleKey('f');
    });
    glfwSetMouseButtonCallback(window, [](GLFWwindow* w, int button, int action, int mods) {
      auto* self = static_cast<Impl*>(glfwGetWindowUserPointer(w));
      const bool pressed = action == GLFW_PRESS;
      glfwGetCursorPos(w, &self->last_x, &self->last_y);
      const bool pan = button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE ||
                       (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_SHIFT));
      if (button == GLFW_MOUSE_BUTTON_LEFT && !pan) self->dragging[0] = pressed;
      if (pan) self->dragging[1] = pressed;
      if (!pressed) self->dragging[0] = self->dragging[1] = false;
    });
    glfwSetCursorPosCallback(window, [](GLFWwindow* w, double x, double y) {
      auto* self = static_cast<Impl*>(glfwGetWindowUserPointer(w));
      const double dx = x - self->last_x;
      const double dy = y - self->last_y;
      self->last_x = x;
      self->last_y = y;
      if (self->dragging[0]) self->HandleDrag(0, dx, dy);
      if (self->dragging[1]) self->HandleDrag(1, dx, dy);
    });
    glfwSetScrollCallback(window, [](GLFWwindow* w, double, double dy) {
      static_cast<Impl*>(glfwGetWindowUserPointer(w))->HandleScroll(dy);
    });
    opened->set_value("");
    Loop();
    renderer.reset();  // frees GL objects while the context is current
    glfwDestroyWindow(window);
    glfwTerminate();
    mailbox.MarkAllDone();
    std::lock_guard<std::mutex> lock(mutex);
    for (auto& request : screenshot_requests) request.set_value(cv::Mat());
    screenshot_requests.clear();
  }

  void Post(std::function<void()> command) {
    std::lock_guard<std::mutex> lock(mutex);
    commands.push_back(std::move(command));
  }
};

PreviewWindow::PreviewWindow(const PreviewOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  bool expected = false;
  SIGHTMAP_CHECK(g_window_open.compare_exchange_strong(expected, true),
                 "a preview window is already open (one per process)");
  impl_ = std::make_unique<Impl>(options);
  std::promise<std::string> opened;
  std::future<std::string> result = opened.get_future();
  impl_->thread = std::thread([this, &opened] { impl_->Run(&opened); });
  const std::string error = result.get();
  if (!error.empty()) {
    impl_->thread.join();
    g_window_open = false;
    SIGHTMAP_THROW(Error, error);
  }
}

PreviewWindow::~PreviewWindow() {
  if (!impl_) return;
  impl_->quit = true;
  if (impl_->thread.joinable()) impl_->thread.join();
  g_window_open = false;
}

void PreviewWindow::Submit(MapUpdate update) { impl_->mailbox.Post(std::move(update)); }

void PreviewWindow::SetLiveImages(const cv::Mat& bgr, const cv::Mat& depth_mm) {
  SIGHTMAP_CHECK(bgr.empty() || bgr.type() == CV_8UC3, "live colour images must be 8-bit BGR");
  SIGHTMAP_CHECK(depth_mm.empty() || depth_mm.type() == CV_16UC1,
                 "live depth images must be 16-bit millimetres");
  cv::Mat bgr_copy = bgr.clone();
  cv::Mat depth_copy = depth_mm.clone();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->live_bgr = std::move(bgr_copy);
  impl_->live_depth = std::move(depth_copy);
  impl_->images_changed = true;
}

bool PreviewWindow::paused() const { return impl_->paused; }
bool PreviewWindow::stop_requested() const { return impl_->stop_requested; }
void PreviewWindow::Finish() { impl_->mailbox.WaitDone(); }
std::string PreviewWindow::description() const { return "preview window"; }

cv::Mat PreviewWindow::Screenshot(std::chrono::milliseconds timeout) {
  std::promise<cv::Mat> request;
  std::future<cv::Mat> result = request.get_future();
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->screenshot_requests.push_back(std::move(request));
  }
  if (result.wait_for(timeout) != std::future_status::ready) return cv::Mat();
  return result.get();
}

void PreviewWindow::InjectKey(char key) {
  Impl* impl = impl_.get();
  impl->Post([impl, key] { impl->HandleKey(key); });
}

void PreviewWindow::InjectDrag(int button, double dx, double dy) {
  Impl* impl = impl_.get();
  impl->Post([impl, button, dx, dy] { impl->HandleDrag(button, dx, dy); });
}

void PreviewWindow::InjectScroll(double dy) {
  Impl* impl = impl_.get();
  impl->Post([impl, dy] { impl->HandleScroll(dy); });
}

int64_t PreviewWindow::frames_drawn() const { return impl_->frames; }
int64_t PreviewWindow::snapshots_written() const { return impl_->snapshots; }
std::string PreviewWindow::last_snapshot() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->last_snapshot;
}

}  // namespace sightmap::render
