// The feed's coverage while mapping, through the real progress writer (OSMesa): a keyframe that
// sees a label turns a sector of its ring green in the written floor plan; one whose depth shows a
// box in front of the label leaves every sector red. Loops switched off leave the floor plan and
// return when switched back on.
#include "mapping/map_view_feed.h"

#include <cstdlib>
#include <functional>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "store/synthetic_model.h"
#include "tests/test_data.h"

namespace sightmap::mapping {
namespace {

// Pixels of `image` within 20 of `bgr` (summed over channels).
int CountNear(const cv::Mat& image, const cv::Vec3b& bgr) {
  int count = 0;
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      const cv::Vec3b& c = image.at<cv::Vec3b>(v, u);
      count += std::abs(c[0] - bgr[0]) + std::abs(c[1] - bgr[1]) + std::abs(c[2] - bgr[2]) < 20;
    }
  }
  return count;
}

// The floor plan written after one keyframe at the origin looking along +z at a label 2 m ahead,
// its depth a wall at 2.5 m, with a box 1 m ahead in front of the label when `boxed`.
cv::Mat FloorPlanAfterOneKeyframe(const std::string& name, bool boxed) {
  MapViewFeedOptions options;
  options.choice = ViewChoice::kHeadless;
  options.progress_png = testing::MakeTempDir(name) + "/progress.png";
  std::unique_ptr<MapViewFeed> feed = MapViewFeed::Create(options, nullptr);
  store::LabelRecord label;
  label.name = "lamp";
  store::LabelPoint point;
  point.world = Eigen::Vector3d(0.0, 0.0, 2.0);
  label.points.push_back(point);
  feed->SetLabels({label});
  const Intrinsics camera = store::SyntheticIntrinsics(640, 480);
  cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(120, 120, 120));
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(2500));
  if (boxed) depth(cv::Rect(270, 190, 100, 100)).setTo(cv::Scalar(1000));
  // A floor below the camera gives the plan its extent.
  bgr(cv::Rect(0, 400, 640, 80)).setTo(cv::Scalar(60, 60, 60));
  feed->AddKeyframe(1, 1, Eigen::Isometry3d::Identity(), bgr, depth, camera);
  feed->Finish();
  const cv::Mat image = cv::imread(options.progress_png);
  EXPECT_FALSE(image.empty()) << options.progress_png;
  return image.empty() ? image : image(cv::Rect(0, 0, image.cols / 2, image.rows)).clone();
}

TEST(MapViewFeed, AKeyframeThatSeesALabelTurnsItsSectorGreen) {
  const cv::Vec3b green(77, 217, 51);  // the ring's colours (render/map_renderer.cc), BGR
  const cv::Vec3b red(38, 38, 191);
  const cv::Mat seen = FloorPlanAfterOneKeyframe("feed_seen", false);
  ASSERT_FALSE(seen.empty());
  EXPECT_GT(CountNear(seen, green), 20);
  EXPECT_GT(CountNear(seen, red), 10 * CountNear(seen, green));  // 11 of 12 sectors unseen
  const cv::Mat hidden = FloorPlanAfterOneKeyframe("feed_hidden", true);
  ASSERT_FALSE(hidden.empty());
  EXPECT_EQ(CountNear(hidden, green), 0);
  EXPECT_GT(CountNear(hidden, red), 100);
}

// The floor plan after three keyframes (a right angle: 2 m along x, then 2 m along z) and the loop
// operations `loops` makes on the feed between the first and the third.
cv::Mat FloorPlanAfterLoops(const std::string& name,
                            const std::function<void(MapViewFeed&)>& loops) {
  MapViewFeedOptions options;
  options.choice = ViewChoice::kHeadless;
  options.progress_png = testing::MakeTempDir(name) + "/progress.png";
  std::unique_ptr<MapViewFeed> feed = MapViewFeed::Create(options, nullptr);
  const Intrinsics camera = store::SyntheticIntrinsics(640, 480);
  const cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(120, 120, 120));
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(2500));
  const Eigen::Vector3d positions[] = {{0, 0, 0}, {2, 0, 0}, {2, 0, 2}};
  for (int id = 1; id <= 3; ++id) {
    feed->AddKeyframe(id, 1, Eigen::Isometry3d(Eigen::Translation3d(positions[id - 1])), bgr, depth,
                      camera);
  }
  loops(*feed);
  feed->Finish();
  const cv::Mat image = cv::imread(options.progress_png);
  EXPECT_FALSE(image.empty()) << options.progress_png;
  return image.empty() ? image : image(cv::Rect(0, 0, image.cols / 2, image.rows)).clone();
}

// The view draws the loops the model holds: a loop switched off after it was drawn leaves the
// floor plan, and one switched back on (the end's solve judging again) returns.
TEST(MapViewFeed, ALoopSwitchedOffLeavesTheMapAndReturnsWhenSwitchedBackOn) {
  const cv::Vec3b magenta(230, 64, 255);  // the loops' colour (render/map_renderer.cc), BGR
  const cv::Mat drawn =
      FloorPlanAfterLoops("feed_loop_on", [](MapViewFeed& feed) { feed.AddLoop(1, 3); });
  ASSERT_FALSE(drawn.empty());
  EXPECT_GT(CountNear(drawn, magenta), 50);
  const cv::Mat removed = FloorPlanAfterLoops("feed_loop_off", [](MapViewFeed& feed) {
    feed.AddLoop(1, 3);
    feed.RemoveLoop(1, 3);
  });
  ASSERT_FALSE(removed.empty());
  EXPECT_EQ(CountNear(removed, magenta), 0);
  const cv::Mat back = FloorPlanAfterLoops("feed_loop_back", [](MapViewFeed& feed) {
    feed.AddLoop(1, 3);
    feed.RemoveLoop(1, 3);
    feed.AddLoop(1, 3);
  });
  ASSERT_FALSE(back.empty());
  EXPECT_GT(CountNear(back, magenta), 50);
}

}  // namespace
}  // namespace sightmap::mapping
