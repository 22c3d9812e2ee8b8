#include "render/map_renderer.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "render/bitmap_font.h"
#include "render/offscreen_context.h"

namespace sightmap::render {
namespace {

// A pose that is not axis-aligned, so frame mix-ups show.
Eigen::Isometry3d SomePose(const Eigen::Vector3d& t, double yaw, double pitch) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  // Camera looking along world +x, z up, then turned.
  Eigen::Matrix3d base;
  base.col(0) = Eigen::Vector3d(0, -1, 0);
  base.col(1) = Eigen::Vector3d(0, 0, -1);
  base.col(2) = Eigen::Vector3d(1, 0, 0);
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * base *
                  Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix();
  pose.translation() = t;
  return pose;
}

// Adds world point `p` with colour `rgb` to the keyframe (stored in its camera frame).
void AddWorldPoint(const Eigen::Vector3d& p, std::array<uint8_t, 3> rgb, MapKeyframe* keyframe) {
  keyframe->points_cam.push_back((keyframe->world_from_cam.inverse() * p).cast<float>());
  keyframe->colors.push_back(rgb);
}

// Centroid of the pure-red pixels inside `viewport` (nullopt if none), and their count.
std::optional<Eigen::Vector2d> RedCentroid(const cv::Mat& image, const Viewport& viewport,
                                           int* count) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  *count = 0;
  for (int v = viewport.y; v < viewport.y + viewport.height; ++v) {
    for (int u = viewport.x; u < viewport.x + viewport.width; ++u) {
      const cv::Vec3b& c = image.at<cv::Vec3b>(v, u);  // BGR
      if (c[2] > 120 && c[1] < 40 && c[0] < 40) {
        sum += Eigen::Vector2d(u - viewport.x, v - viewport.y);
        ++*count;
      }
    }
  }
  if (*count == 0) return std::nullopt;
  return sum / *count;
}

// A floor of grey points 8 x 5 m with walls, and one red point at `red`.
MapScene KnownScene(const Eigen::Vector3d& red, MapKeyframe* keyframe_out = nullptr) {
  MapScene scene;
  MapUpdate update;
  MapKeyframe keyframe;
  keyframe.id = 1;
  keyframe.world_from_cam = SomePose(Eigen::Vector3d(1.0, 1.0, 1.5), 0.4, -0.2);
  for (double x = -2.0; x <= 6.0; x += 0.5) {
    for (double y = -1.0; y <= 4.0; y += 0.5) {
      AddWorldPoint(Eigen::Vector3d(x, y, 0.0), {90, 90, 90}, &keyframe);
    }
  }
  AddWorldPoint(red, {255, 0, 0}, &keyframe);
  if (keyframe_out != nullptr) *keyframe_out = keyframe;
  update.keyframes.push_back(keyframe);
  // The current camera looks at the red point from 2.5 m.
  update.camera = SomePose(red + Eigen::Vector3d(-2.5, 0.3, 0.5), 0.0, -0.1);
  scene.Apply(std::move(update));
  return scene;
}

MapRenderOptions ExactOptions() {
  MapRenderOptions options;
  options.width = 800;
  options.height = 400;
  options.point_size_px = 1.0f;  // one pixel per point: the centroid is the pixel itself
  return options;
}

TEST(MapRenderer, ProgressImageHasTheSizeAndIsNotBlank) {
  OffscreenContext context(16, 16);
  const MapRenderOptions options = ExactOptions();
  context.Resize(options.width, options.height);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  const MapScene scene = KnownScene(Eigen::Vector3d(3.0, 2.0, 1.0));
  renderer.DrawProgress(scene, options.width, options.height);
  const cv::Mat image = renderer.ReadImage(options.width, options.height);
  ASSERT_EQ(image.cols, 800);
  ASSERT_EQ(image.rows, 400);
  ASSERT_EQ(image.type(), CV_8UC3);
  // Pixels that differ from the background: the points, text, trajectory and frustum.
  const cv::Vec3b background(23, 18, 18);  // options.background_rgb in BGR
  int drawn = 0;
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      const cv::Vec3b& c = image.at<cv::Vec3b>(v, u);
      drawn += std::abs(c[0] - background[0]) + std::abs(c[1] - background[1]) +
                   std::abs(c[2] - background[2]) >
               30;
    }
  }
  EXPECT_GT(drawn, 2000);
  EXPECT_LT(drawn, image.rows * image.cols / 2);
  // Both halves have content.
  cv::Scalar left_std, right_std, mean;
  cv::meanStdDev(image(cv::Rect(0, 0, 400, 400)), mean, left_std);
  cv::meanStdDev(image(cv::Rect(400, 0, 400, 400)), mean, right_std);
  EXPECT_GT(left_std[1], 5.0);
  EXPECT_GT(right_std[1], 5.0);
}

// One red point in an otherwise grey map lands where each view's projection puts it.
TEST(MapRenderer, KnownPointLandsWhereTheViewsProjectIt) {
  OffscreenContext context(16, 16);
  const MapRenderOptions options = ExactOptions();
  context.Resize(options.width, options.height);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  const Eigen::Vector3d red(3.2, 2.3, 1.0);
  const MapScene scene = KnownScene(red);
  renderer.DrawProgress(scene, options.width, options.height);
  const cv::Mat image = renderer.ReadImage(options.width, options.height);
  const ProgressLayout layout = MakeProgressLayout(scene, options.width, options.height, options);

  // Floor plan, by hand: orthographic, x right, y up, centred on the extent's centre.
  const ViewCamera& top = layout.top_down;
  ASSERT_TRUE(top.orthographic);
  const double px_per_m = top.intrinsics.fx;
  const Eigen::Vector3d centre = top.world_from_cam.translation();
  const Eigen::Vector2d top_expected(top.intrinsics.cx + px_per_m * (red.x() - centre.x()),
                                     top.intrinsics.cy - px_per_m * (red.y() - centre.y()));
  const std::optional<Eigen::Vector2d> top_projected = top.Project(red);
  ASSERT_TRUE(top_projected.has_value());
  EXPECT_NEAR((*top_projected - top_expected).norm(), 0.0, 1e-9);
  // The floor (x in [-2, 6], y in [-1, 4]) fills the panel's width minus the margins.
  EXPECT_NEAR(px_per_m, 400 * (1 - 2 * options.top_down_margin) / 8.0, 1e-4);  // points are floats
  int count = 0;
  const std::optional<Eigen::Vector2d> top_found =
      RedCentroid(image, layout.top_down_viewport, &count);
  ASSERT_TRUE(top_found.has_value()) << "no red pixel in the floor plan";
  EXPECT_LE(count, 2);
  EXPECT_NEAR(top_found->x(), top_expected.x(), 0.75);
  EXPECT_NEAR(top_found->y(), top_expected.y(), 0.75);

  // Follow view: a pinhole camera, Intrinsics::Project of the point in its camera frame.
  const ViewCamera& follow = layout.follow;
  ASSERT_FALSE(follow.orthographic);
  const Eigen::Vector3d in_cam = follow.world_from_cam.inverse() * red;
  ASSERT_GT(in_cam.z(), 0.0);
  const Eigen::Vector2d follow_expected = follow.intrinsics.Project(in_cam);
  ASSERT_GT(follow_expected.x(), 0);
  ASSERT_LT(follow_expected.x(), layout.follow_viewport.width);
  const std::optional<Eigen::Vector2d> follow_found =
      RedCentroid(image, layout.follow_viewport, &count);
  ASSERT_TRUE(follow_found.has_value()) << "no red pixel in the camera view";
  EXPECT_LE(count, 2);
  EXPECT_NEAR(follow_found->x(), follow_expected.x(), 0.75);
  EXPECT_NEAR(follow_found->y(), follow_expected.y(), 0.75);

  // The follow camera is behind and above the current camera, which it sees near its centre.
  const Eigen::Vector3d camera_in_follow =
      follow.world_from_cam.inverse() * scene.camera()->translation();
  EXPECT_NEAR(camera_in_follow.z(), std::hypot(options.follow_distance_m, options.follow_height_m),
              0.5);
  EXPECT_NEAR(follow.intrinsics.Project(camera_in_follow).x(), follow.intrinsics.cx, 1.0);
}

// Moving a keyframe (loop closure) moves its points without uploading them again; adding a
// keyframe uploads only its own points.
TEST(MapRenderer, PoseUpdateMovesPointsWithoutUploadAndAddingUploadsOnlyTheNewKeyframe) {
  OffscreenContext context(16, 16);
  const MapRenderOptions options = ExactOptions();
  context.Resize(options.width, options.height);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  const Eigen::Vector3d red(3.2, 2.3, 1.0);
  MapKeyframe keyframe;
  MapScene scene = KnownScene(red, &keyframe);
  renderer.Sync(scene);
  ASSERT_EQ(renderer.num_uploads(), 1u);
  ASSERT_EQ(renderer.num_uploaded_points(), keyframe.points_cam.size());

  // Shift the keyframe 0.5 m along world x.
  MapUpdate move;
  Eigen::Isometry3d moved = keyframe.world_from_cam;
  moved.translation().x() += 0.5;
  move.poses.push_back({1, moved});
  scene.Apply(std::move(move));
  renderer.DrawProgress(scene, options.width, options.height);
  EXPECT_EQ(renderer.num_uploads(), 1u);
  const cv::Mat image = renderer.ReadImage(options.width, options.height);
  const ProgressLayout layout = MakeProgressLayout(scene, options.width, options.height, options);
  const std::optional<Eigen::Vector2d> expected =
      layout.top_down.Project(red + Eigen::Vector3d(0.5, 0, 0));
  ASSERT_TRUE(expected.has_value());
  int count = 0;
  const std::optional<Eigen::Vector2d> found = RedCentroid(image, layout.top_down_viewport, &count);
  ASSERT_TRUE(found.has_value());
  EXPECT_NEAR((*found - *expected).norm(), 0.0, 1.0);

  MapUpdate add;
  MapKeyframe second;
  second.id = 2;
  second.world_from_cam = moved;
  AddWorldPoint(Eigen::Vector3d(0, 0, 0.5), {0, 0, 255}, &second);
  AddWorldPoint(Eigen::Vector3d(0, 1, 0.5), {0, 0, 255}, &second);
  add.keyframes.push_back(second);
  scene.Apply(std::move(add));
  renderer.Sync(scene);
  EXPECT_EQ(renderer.num_uploads(), 2u);
  EXPECT_EQ(renderer.num_uploaded_points(), keyframe.points_cam.size() + 2);
}

TEST(BitmapFont, GlyphsTextSizeAndCpuDrawing) {
  // 'A': a rounded top, a bar in the middle, two legs.
  const auto& a = Glyph5x7('A');
  EXPECT_EQ(a[0], 0x0e);
  EXPECT_EQ(a[3], 0x1f);
  EXPECT_EQ(a[6], 0x11);
  EXPECT_EQ(Glyph5x7('\x01'), Glyph5x7('?'));
  // Every printable character but space has a lit pixel, and no two share a bitmap (bar the
  // space, which is blank).
  for (int c = 33; c <= 126; ++c) {
    const auto& g = Glyph5x7(static_cast<char>(c));
    int lit = 0;
    for (uint8_t row : g) lit += __builtin_popcount(row);
    EXPECT_GT(lit, 0) << static_cast<char>(c);
    for (int d = c + 1; d <= 126; ++d) {
      EXPECT_NE(g, Glyph5x7(static_cast<char>(d))) << static_cast<char>(c) << static_cast<char>(d);
    }
  }
  EXPECT_EQ(TextWidthPx("ab", 2), (6 + 5) * 2);
  EXPECT_EQ(TextHeightPx("a\nb", 1), 9 + 7);
  cv::Mat image(10, 10, CV_8UC3, cv::Scalar(0, 0, 0));
  DrawText("A", cv::Point(1, 1), 1, cv::Vec3b(255, 255, 255), &image);
  for (int row = 0; row < kGlyphHeight; ++row) {
    for (int col = 0; col < kGlyphWidth; ++col) {
      const bool lit = (a[static_cast<size_t>(row)] >> (4 - col)) & 1;
      EXPECT_EQ(image.at<cv::Vec3b>(1 + row, 1 + col)[0], lit ? 255 : 0) << row << "," << col;
    }
  }
}

// Text drawn by GL matches the glyph table pixel for pixel.
TEST(BitmapFont, GlTextMatchesTheGlyphTable) {
  OffscreenContext context(64, 32);
  MapRenderer renderer(&OffscreenContext::ProcAddress);
  renderer.BeginFrame(64, 32);
  renderer.DrawText("Kg", 10, 8, 1, Eigen::Vector3f(1, 1, 1));
  const cv::Mat image = renderer.ReadImage(64, 32);
  int mismatches = 0;
  for (int i = 0; i < 2; ++i) {
    const auto& glyph = Glyph5x7("Kg"[i]);
    for (int row = 0; row < kGlyphHeight; ++row) {
      for (int col = 0; col < kGlyphWidth; ++col) {
        const bool lit = (glyph[static_cast<size_t>(row)] >> (4 - col)) & 1;
        const int value = image.at<cv::Vec3b>(8 + row, 10 + i * kGlyphAdvance + col)[1];
        mismatches += lit != (value > 200);
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(MapScene, FromRgbdAveragesAFlatWallPerVoxel) {
  Intrinsics k = Intrinsics::FromFieldOfView(320, 240, 1.0, 0.0);
  cv::Mat bgr(240, 320, CV_8UC3, cv::Scalar(10, 100, 200));
  cv::Mat depth(240, 320, CV_16UC1, cv::Scalar(2000));
  depth(cv::Rect(0, 0, 40, 240)).setTo(0);      // no measurement
  depth(cv::Rect(40, 0, 20, 240)).setTo(9000);  // beyond max_depth_m
  KeyframeCloudOptions options;
  options.voxel_m = 0.1;
  const MapKeyframe keyframe = FromRgbd(bgr, depth, k, options);
  ASSERT_EQ(keyframe.points_cam.size(), keyframe.colors.size());
  // The wall spans (260 x 240 px) * (2 m / fx) => its area over a 0.1 m grid.
  const double metres_per_px = 2.0 / k.fx;
  const double cells = (260 * metres_per_px / 0.1) * (240 * metres_per_px / 0.1);
  EXPECT_GT(keyframe.points_cam.size(), 0.9 * cells);
  EXPECT_LT(keyframe.points_cam.size(), 1.3 * cells + 60);
  for (size_t i = 0; i < keyframe.points_cam.size(); ++i) {
    EXPECT_NEAR(keyframe.points_cam[i].z(), 2.0f, 1e-4f);
    EXPECT_GT(keyframe.points_cam[i].x(), (40 + 20 - k.cx - 0.5) * metres_per_px);
    EXPECT_EQ(keyframe.colors[i][0], 200);  // RGB
    EXPECT_EQ(keyframe.colors[i][2], 10);
  }
  EXPECT_THROW(FromRgbd(bgr, cv::Mat(240, 320, CV_32F), k), Error);
}

TEST(MapScene, MergedUpdatesEqualUpdatesInOrder) {
  MapUpdate a;
  MapKeyframe keyframe;
  keyframe.id = 7;
  a.keyframes.push_back(keyframe);
  a.poses.push_back({7, Eigen::Isometry3d(Eigen::Translation3d(1, 0, 0))});
  a.status = MapStatus{1, 0, TrackingState::kLost, 0.5, 2.0};
  MapUpdate b;
  b.poses.push_back({7, Eigen::Isometry3d(Eigen::Translation3d(2, 0, 0))});
  b.loops.push_back({7, 7});
  b.status = MapStatus{1, 1, TrackingState::kRelocalised, 0.5, 3.0};
  a.Merge(std::move(b));
  EXPECT_EQ(a.poses.size(), 1u);  // coalesced per keyframe
  MapScene scene;
  scene.Apply(std::move(a));
  EXPECT_DOUBLE_EQ(scene.keyframes().at(7).world_from_cam.translation().x(), 2.0);
  EXPECT_EQ(scene.loops().size(), 1u);
  EXPECT_EQ(scene.status().tracking, TrackingState::kRelocalised);
}

// A removed loop takes one edge with its ends out of the scene; merged batches keep the order the
// feed sent them in: a loop added then removed is gone, removed then added again is drawn.
TEST(MapScene, RemovedLoopsLeaveTheSceneInTheOrderSent) {
  const auto apply_in_order = [](std::vector<MapUpdate> updates, bool merged) {
    MapScene scene;
    MapUpdate first;
    first.loops = {{1, 2}, {1, 2}, {3, 4}};  // two loops may join the same keyframes
    scene.Apply(std::move(first));
    if (merged) {
      for (size_t i = 1; i < updates.size(); ++i) updates[0].Merge(std::move(updates[i]));
      updates.resize(1);
    }
    for (MapUpdate& update : updates) scene.Apply(std::move(update));
    return scene.loops();
  };
  const auto loops_of = [](std::vector<LoopEdge> add, std::vector<LoopEdge> remove) {
    MapUpdate update;
    update.loops = std::move(add);
    update.removed_loops = std::move(remove);
    return update;
  };
  for (bool merged : {false, true}) {
    SCOPED_TRACE(merged ? "merged" : "one at a time");
    std::vector<MapUpdate> off_on_off;
    off_on_off.push_back(loops_of({}, {{3, 4}}));
    off_on_off.push_back(loops_of({{3, 4}}, {}));
    off_on_off.push_back(loops_of({}, {{3, 4}, {1, 2}}));
    off_on_off.push_back(loops_of({{5, 6}}, {{7, 8}}));  // an unknown loop removes nothing
    EXPECT_EQ(apply_in_order(std::move(off_on_off), merged),
              (std::vector<LoopEdge>{{1, 2}, {5, 6}}));
    std::vector<MapUpdate> on_off_on;
    on_off_on.push_back(loops_of({{9, 10}}, {}));
    on_off_on.push_back(loops_of({}, {{9, 10}}));
    on_off_on.push_back(loops_of({{9, 10}}, {}));
    EXPECT_EQ(apply_in_order(std::move(on_off_on), merged),
              (std::vector<LoopEdge>{{1, 2}, {1, 2}, {3, 4}, {9, 10}}));
  }
  MapUpdate only_removal;
  only_removal.removed_loops.push_back({1, 2});
  EXPECT_FALSE(only_removal.empty());
}

// Sightings count for the sector their keyframe stands in now, within the distance band; a pose
// update that moves a keyframe moves its sector; merged updates keep every sighting.
TEST(MapScene, SeenSectorsFollowTheSightingKeyframesPoses) {
  MapScene scene;  // z up: bearing 0 along world x, 90 along y
  MapUpdate update;
  update.appliances = std::vector<ApplianceLabel>{{"lamp", Eigen::Vector3d(1.0, 1.0, 1.0)},
                                                  {"tv", Eigen::Vector3d(9.0, 9.0, 1.0)}};
  const auto at = [](int64_t id, const Eigen::Vector3d& position) {
    MapKeyframe keyframe;
    keyframe.id = id;
    keyframe.world_from_cam = Eigen::Isometry3d(Eigen::Translation3d(position));
    return keyframe;
  };
  update.keyframes = {at(1, {3.0, 1.0, 1.5}),    // 2 m along +x of the lamp: bearing 0
                      at(2, {1.0, 3.5, 1.2}),    // +y, 2.5 m: bearing 90, sector 3
                      at(3, {1.0, 1.5, 1.5}),    // too near (0.7 m)
                      at(4, {-5.0, 1.0, 1.5})};  // too far (6 m)
  update.sightings = {{1, 0}, {2, 0}, {3, 0}};
  MapUpdate later;
  later.sightings = {{4, 0}, {99, 0}, {1, 7}};  // an unknown keyframe, an unknown appliance
  update.Merge(std::move(later));
  EXPECT_EQ(update.sightings.size(), 6u);
  scene.Apply(std::move(update));
  std::vector<uint64_t> seen = scene.SeenSectors(SectorOptions());
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0], (uint64_t{1} << 0) | (uint64_t{1} << 3));
  EXPECT_EQ(seen[1], 0u);
  // Loop closure moves keyframe 1 to -y of the lamp (bearing 270: sector 9).
  MapUpdate moved;
  moved.poses.push_back({1, Eigen::Isometry3d(Eigen::Translation3d(1.0, -1.0, 1.5))});
  scene.Apply(std::move(moved));
  seen = scene.SeenSectors(SectorOptions());
  EXPECT_EQ(seen[0], (uint64_t{1} << 9) | (uint64_t{1} << 3));
  EXPECT_NEAR((scene.FloorDirection(90.0) - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);
  EXPECT_EQ(CoverageLine(scene, SectorOptions()), "labels 2  seen from 2 of 24 directions");
  EXPECT_EQ(CoverageLine(MapScene(), SectorOptions()), "");
  SectorOptions bad;
  bad.sectors = 65;
  EXPECT_THROW(scene.SeenSectors(bad), Error);
}

// Counts the pixels of `image` within `radius` px of `centre` that are near `bgr`.
int PixelsNear(const cv::Mat& image, const Eigen::Vector2d& centre, double radius,
               const cv::Vec3b& bgr) {
  int count = 0;
  for (int v = std::max(0, static_cast<int>(centre.y() - radius));
       v < std::min(image.rows, static_cast<int>(centre.y() + radius) + 1); ++v) {
    for (int u = std::max(0, static_cast<int>(centre.x() - radius));
         u < std::min(image.cols, static_cast<int>(centre.x() + radius) + 1); ++u) {
      const cv::Vec3b& c = image.at<cv::Vec3b>(v, u);
      if (std::abs(c[0] - bgr[0]) + std::abs(c[1] - bgr[1]) + std::abs(c[2] - bgr[2]) < 40) {
        ++count;
      }
    }
  }
  return count;
}

// The floor plan rings each appliance: green on the side a keyframe saw it from, red elsewhere.
TEST(MapRenderer, TheFloorPlanRingsEachApplianceGreenWhereItWasSeenFrom) {
  OffscreenContext context(16, 16);
  const MapRenderOptions options = ExactOptions();
  context.Resize(options.width, options.height);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  const Eigen::Vector3d lamp(2.0, 1.5, 1.0);
  MapScene scene = KnownScene(Eigen::Vector3d(3.0, 2.0, 1.0));
  MapUpdate update;
  update.appliances = std::vector<ApplianceLabel>{{"lamp", lamp}};
  update.sightings.push_back({1, 0});  // KnownScene's keyframe stands at (1, 1, 1.5): bearing 207
  scene.Apply(std::move(update));
  renderer.DrawProgress(scene, options.width, options.height);
  const cv::Mat image = renderer.ReadImage(options.width, options.height);
  const ProgressLayout layout = MakeProgressLayout(scene, options.width, options.height, options);
  const std::optional<Eigen::Vector2d> centre = layout.top_down.Project(lamp);
  ASSERT_TRUE(centre.has_value());
  const cv::Vec3b green(77, 217, 51);  // (0.2, 0.85, 0.3) in BGR
  const cv::Vec3b red(38, 38, 191);
  const double ring = 7.0 * options.text_scale;  // between the ring's radii
  const auto side = [&](double bearing_deg) {
    const Eigen::Vector2d tip = *layout.top_down.Project(lamp + scene.FloorDirection(bearing_deg));
    return Eigen::Vector2d(*centre + ring * (tip - *centre).normalized());
  };
  EXPECT_GT(PixelsNear(image, side(195.0), 2.5, green), 5);  // the sector of 180-210 degrees
  EXPECT_EQ(PixelsNear(image, side(195.0), 2.5, red), 0);
  for (const double bearing : {15.0, 105.0, 285.0}) {
    EXPECT_GT(PixelsNear(image, side(bearing), 2.5, red), 5) << bearing;
    EXPECT_EQ(PixelsNear(image, side(bearing), 2.5, green), 0) << bearing;
  }
  // Not on the camera view, and not at all with show_coverage off.
  EXPECT_EQ(PixelsNear(image, Eigen::Vector2d(600, 200), 200, green), 0);
  MapRenderOptions without = options;
  without.show_coverage = false;
  MapRenderer plain(&OffscreenContext::ProcAddress, without);
  plain.DrawProgress(scene, options.width, options.height);
  const cv::Mat image_without = plain.ReadImage(options.width, options.height);
  EXPECT_EQ(PixelsNear(image_without, *centre, ring + 4.0, green), 0);
  EXPECT_EQ(PixelsNear(image_without, *centre, ring + 4.0, red), 0);
}

// Blue-ish session 1 against pink-ish session 2, and the loops in magenta: on the floor plan the
// walk of each session is a polyline of its colour, and a loop edge joins its two keyframes.
TEST(MapRenderer, TheFloorPlanDrawsEachSessionsWalkAndTheLoopsInTheirColours) {
  OffscreenContext context(16, 16);
  const MapRenderOptions options = ExactOptions();
  context.Resize(options.width, options.height);
  MapRenderer renderer(&OffscreenContext::ProcAddress, options);
  MapScene scene;
  MapUpdate update;
  const auto add_keyframe = [&update](int64_t id, int session, const Eigen::Vector3d& at) {
    MapKeyframe keyframe;
    keyframe.id = id;
    keyframe.session = session;
    keyframe.world_from_cam = SomePose(at, 0.0, 0.0);
    AddWorldPoint(at + Eigen::Vector3d(0.0, 0.0, -1.5), {90, 90, 90}, &keyframe);
    update.keyframes.push_back(keyframe);
  };
  add_keyframe(1, 1, {0.0, 0.0, 1.5});
  add_keyframe(2, 1, {4.0, 0.0, 1.5});
  add_keyframe(3, 1, {4.0, 4.0, 1.5});
  add_keyframe(4, 2, {0.0, 4.0, 1.5});
  add_keyframe(5, 2, {0.0, 2.0, 1.5});
  update.loops.push_back({3, 1});
  scene.Apply(std::move(update));
  renderer.DrawProgress(scene, options.width, options.height);
  const cv::Mat image = renderer.ReadImage(options.width, options.height);
  const ProgressLayout layout = MakeProgressLayout(scene, options.width, options.height, options);
  const auto pixel = [&](const Eigen::Vector3d& world) {
    const std::optional<Eigen::Vector2d> at = layout.top_down.Project(world);
    EXPECT_TRUE(at.has_value());
    return at.value_or(Eigen::Vector2d::Zero());
  };
  const auto bgr = [](const Eigen::Vector3f& rgb) {
    return cv::Vec3b(static_cast<uint8_t>(255 * rgb.z()), static_cast<uint8_t>(255 * rgb.y()),
                     static_cast<uint8_t>(255 * rgb.x()));
  };
  const cv::Vec3b first = bgr(SessionColor(1));
  const cv::Vec3b second = bgr(SessionColor(2));
  const cv::Vec3b loop = bgr(Eigen::Vector3f(1.0f, 0.25f, 0.9f));
  // Halfway along each session's steps, and along the loop 3 -> 1.
  const Eigen::Vector2d step_1_2 = pixel({2.0, 0.0, 1.5});
  const Eigen::Vector2d step_4_5 = pixel({0.0, 3.0, 1.5});
  const Eigen::Vector2d loop_3_1 = pixel({2.0, 2.0, 1.5});
  EXPECT_GT(PixelsNear(image, step_1_2, 2.0, first), 2);
  EXPECT_EQ(PixelsNear(image, step_1_2, 2.0, second), 0);
  EXPECT_GT(PixelsNear(image, step_4_5, 2.0, second), 2);
  EXPECT_EQ(PixelsNear(image, step_4_5, 2.0, first), 0);
  EXPECT_GT(PixelsNear(image, loop_3_1, 2.0, loop), 2);
  // Sessions are not joined to one another: nothing between keyframe 3 and keyframe 4.
  const Eigen::Vector2d between_sessions = pixel({2.0, 4.0, 1.5});
  EXPECT_EQ(PixelsNear(image, between_sessions, 2.0, first), 0);
  EXPECT_EQ(PixelsNear(image, between_sessions, 2.0, second), 0);
}

}  // namespace
}  // namespace sightmap::render
