// Run by ctest twice: render_preview_test under `xvfb-run -a` (PreviewWindow.*, Factory.*) and
// render_preview_fallback_test with no display (NoDisplay.*).
#include "render/preview_window.h"

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "core/check.h"
#include "core/timing.h"
#include "render/map_view_factory.h"
#include "tests/test_data.h"

namespace sightmap::render {
namespace {

MapUpdate SmallMap() {
  MapUpdate update;
  for (int64_t id = 0; id < 20; ++id) {
    MapKeyframe keyframe;
    keyframe.id = id;
    keyframe.session = 1 + static_cast<int>(id / 10);
    Eigen::Matrix3d r;
    r.col(0) = Eigen::Vector3d(0, -1, 0);
    r.col(1) = Eigen::Vector3d(0, 0, -1);
    r.col(2) = Eigen::Vector3d(1, 0, 0);
    keyframe.world_from_cam.linear() =
        Eigen::AngleAxisd(0.3 * id, Eigen::Vector3d::UnitZ()).toRotationMatrix() * r;
    keyframe.world_from_cam.translation() = Eigen::Vector3d(0.3 * id, 0.1 * id, 1.4);
    for (int i = 0; i < 2000; ++i) {
      const float a = 0.01f * i;
      keyframe.points_cam.emplace_back(std::sin(a) * 1.5f, std::cos(3 * a) * 0.8f,
                                       2.0f + 0.3f * std::sin(7 * a));
      keyframe.colors.push_back({static_cast<uint8_t>(100 + i % 150), 200, 80});
    }
    update.keyframes.push_back(std::move(keyframe));
  }
  update.loops.push_back({2, 18});
  update.camera = update.keyframes.back().world_from_cam;
  update.appliances = std::vector<ApplianceLabel>{{"lamp", Eigen::Vector3d(2, 1, 1)}};
  return update;
}

// Share of pixels that differ from the background by more than a little.
double DrawnShare(const cv::Mat& image, const cv::Rect& area) {
  const cv::Vec3b background(23, 18, 18);
  int drawn = 0;
  for (int v = area.y; v < area.y + area.height; ++v) {
    for (int u = area.x; u < area.x + area.width; ++u) {
      const cv::Vec3b& c = image.at<cv::Vec3b>(v, u);
      drawn += std::abs(c[0] - background[0]) + std::abs(c[1] - background[1]) +
                   std::abs(c[2] - background[2]) >
               30;
    }
  }
  return static_cast<double>(drawn) / area.area();
}

TEST(PreviewWindow, OpensDrawsAMapTakesScreenshotsHandlesKeysAndClosesCleanly) {
  ASSERT_NE(std::getenv("DISPLAY"), nullptr) << "run under xvfb-run (ctest does)";
  const std::string dir = sightmap::testing::MakeTempDir("snapshots");
  PreviewOptions options;
  options.width = 960;
  options.height = 540;
  options.snapshot_dir = dir;
  auto window = std::make_unique<PreviewWindow>(options);
  window->Submit(SmallMap());
  const cv::Mat blue(240, 320, CV_8UC3, cv::Scalar(255, 0, 0));  // BGR
  cv::Mat depth(240, 320, CV_16UC1, cv::Scalar(2500));
  window->SetLiveImages(blue, depth);
  window->Finish();  // everything submitted is drawn

  const cv::Mat shot = window->Screenshot();
  ASSERT_EQ(shot.cols, 960);
  ASSERT_EQ(shot.rows, 540);
  // The 3D view (left two thirds) shows the map, not just the background.
  const double map_share = DrawnShare(shot, cv::Rect(0, 0, 640, 540));
  EXPECT_GT(map_share, 0.02);
  // The colour panel (top right) shows the live image: pure blue at its centre.
  const cv::Vec3b colour_centre = shot.at<cv::Vec3b>(90, 800);
  EXPECT_GT(colour_centre[0], 200);
  EXPECT_LT(colour_centre[2], 40);
  // The depth panel (middle right) is colour-mapped, not background.
  EXPECT_GT(DrawnShare(shot, cv::Rect(700, 200, 200, 140)), 0.9);

  // Space toggles pause; `s` writes a snapshot; a drag orbits the view; `q` asks to stop.
  EXPECT_FALSE(window->paused());
  window->InjectKey(' ');
  window->Screenshot();
  EXPECT_TRUE(window->paused());
  window->InjectKey(' ');
  window->Screenshot();
  EXPECT_FALSE(window->paused());
  window->InjectKey('s');
  window->Screenshot();
  window->Screenshot();
  EXPECT_EQ(window->snapshots_written(), 1);
  const cv::Mat snapshot = cv::imread(window->last_snapshot(), cv::IMREAD_COLOR);
  EXPECT_EQ(snapshot.cols, 960);
  EXPECT_FALSE(std::filesystem::exists(window->last_snapshot() + ".tmp"));
  const cv::Mat before = window->Screenshot();
  window->InjectDrag(0, 120, 40);
  window->InjectScroll(2);
  const cv::Mat after = window->Screenshot();
  cv::Mat difference;
  cv::absdiff(before(cv::Rect(0, 0, 640, 540)), after(cv::Rect(0, 0, 640, 540)), difference);
  EXPECT_GT(cv::countNonZero(difference.reshape(1)), 1000);
  EXPECT_FALSE(window->stop_requested());
  window->InjectKey('q');
  window->Screenshot();
  EXPECT_TRUE(window->stop_requested());
  EXPECT_GT(window->frames_drawn(), 5);

  const auto start = std::chrono::steady_clock::now();
  window.reset();
  EXPECT_LT(SecondsSince(start), 5.0);
  // The window is gone: a new one can open.
  PreviewWindow again(options);
  EXPECT_FALSE(again.Screenshot().empty());
}

TEST(Factory, PreviewAndAutoOpenTheWindowWhenThereIsADisplay) {
  ASSERT_NE(std::getenv("DISPLAY"), nullptr) << "run under xvfb-run (ctest does)";
  MapViewOptions options;
  options.preview.visible = false;
  std::ostringstream notices;
  options.mode = ViewMode::kAuto;
  EXPECT_EQ(CreateMapView(options, &notices)->description(), "preview window");
  options.mode = ViewMode::kPreview;
  EXPECT_EQ(CreateMapView(options, &notices)->description(), "preview window");
  options.mode = ViewMode::kHeadless;
  EXPECT_NE(CreateMapView(options, &notices)->description(), "preview window");
  EXPECT_EQ(notices.str(), "");
}

TEST(NoDisplay, AutoFallsBackToOffscreenWithAOneLineNoticeAndPreviewThrows) {
  unsetenv("DISPLAY");
  unsetenv("WAYLAND_DISPLAY");
  const std::string png = sightmap::testing::MakeTempDir("progress") + "/fallback.png";
  MapViewOptions options;
  options.progress.png_path = png;
  options.progress.every_n_keyframes = 5;
  options.progress.render.width = 320;
  options.progress.render.height = 180;
  std::ostringstream notices;
  std::unique_ptr<MapView> view = CreateMapView(options, &notices);
  ASSERT_NE(view, nullptr);
  EXPECT_EQ(view->description(), "progress images (" + png + ")");
  const std::string notice = notices.str();
  EXPECT_NE(notice.find("no display"), std::string::npos) << notice;
  EXPECT_NE(notice.find("off-screen"), std::string::npos) << notice;
  EXPECT_EQ(std::count(notice.begin(), notice.end(), '\n'), 1) << notice;
  view->Submit(SmallMap());
  view->Finish();
  EXPECT_EQ(cv::imread(png, cv::IMREAD_COLOR).cols, 320);
  EXPECT_FALSE(view->paused());
  EXPECT_FALSE(view->stop_requested());

  // Asking for the window without a display is an error with GLFW's reason, not a crash.
  options.mode = ViewMode::kPreview;
  try {
    CreateMapView(options, &notices);
    ADD_FAILURE() << "the preview window opened without a display";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("GLFW"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sightmap::render
