// The see-through check's grid of view frusta, on views spread over a floor.
#include "identify/visibility.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::identify {
namespace {

// Views 80x60 on a 30 x 12 m floor at eye height, turned at random about the vertical (z), their
// depth a constant 1-8 m.
std::vector<SightingView> ViewsOnAFloor(int count, std::mt19937* rng) {
  std::uniform_real_distribution<double> x(0.0, 30.0);
  std::uniform_real_distribution<double> y(0.0, 12.0);
  std::uniform_real_distribution<double> yaw(-M_PI, M_PI);
  std::uniform_real_distribution<double> depth_m(1.0, 8.0);
  const Intrinsics intrinsics = Intrinsics::FromFieldOfView(80, 60, 1.0, -1.0);
  std::vector<SightingView> views;
  for (int i = 0; i < count; ++i) {
    // Camera z along the floor, y down.
    Eigen::Matrix3d level;
    level << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
    world_from_cam.linear() = Eigen::AngleAxisd(yaw(*rng), Eigen::Vector3d::UnitZ()) * level;
    world_from_cam.translation() = Eigen::Vector3d(x(*rng), y(*rng), 1.5);
    SightingView view;
    view.depth_mm = cv::Mat(60, 80, CV_16UC1, cv::Scalar(std::lround(1000.0 * depth_m(*rng))));
    view.intrinsics = intrinsics;
    view.cam_from_world = world_from_cam.inverse();
    views.push_back(view);
  }
  return views;
}

// Whether the view's image holds `p` in front of it and no farther than its depth.
bool Reaches(const SightingView& view, const Eigen::Vector3d& p) {
  const Eigen::Vector3d cam = view.cam_from_world * p;
  if (!(cam.z() > 0.0)) return false;
  const Eigen::Vector2d pixel = view.intrinsics.Project(cam);
  const long u = std::lround(pixel.x());
  const long v = std::lround(pixel.y());
  if (u < 0 || v < 0 || u >= view.depth_mm.cols || v >= view.depth_mm.rows) return false;
  return cam.z() <= view.depth_mm.at<uint16_t>(static_cast<int>(v), static_cast<int>(u)) * 1e-3;
}

TEST(ViewGridTest, ListsEveryViewThatReachesAPointAndFewOthers) {
  std::mt19937 rng(3);
  const std::vector<SightingView> views = ViewsOnAFloor(300, &rng);
  const ViewGrid grid(views, 1.0);
  std::uniform_real_distribution<double> x(-2.0, 32.0);
  std::uniform_real_distribution<double> y(-2.0, 14.0);
  std::uniform_real_distribution<double> z(0.0, 3.0);
  size_t reaching = 0;
  size_t listed = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d p(x(rng), y(rng), z(rng));
    const std::vector<uint32_t>& near = grid.ViewsNear(p);
    listed += near.size();
    for (size_t v = 0; v < views.size(); ++v) {
      if (!Reaches(views[v], p)) continue;
      ++reaching;
      EXPECT_NE(std::find(near.begin(), near.end(), static_cast<uint32_t>(v)), near.end())
          << "view " << v << " reaches (" << p.transpose() << ") but is not listed";
    }
  }
  ASSERT_GT(reaching, 1000u);
  // The test a point makes is against a small part of the floor's views.
  EXPECT_LT(static_cast<double>(listed) / 3000.0, 0.25 * static_cast<double>(views.size()));
}

TEST(ViewGridTest, AViewThatMeasuredNothingIsNeverListed) {
  std::mt19937 rng(4);
  std::vector<SightingView> views = ViewsOnAFloor(1, &rng);
  views[0].depth_mm.setTo(0);
  const ViewGrid grid(views, 1.0);
  EXPECT_EQ(grid.entries(), 0u);
  EXPECT_TRUE(grid.ViewsNear(views[0].cam_from_world.inverse().translation()).empty());
}

TEST(OcclusionCloudBuilderTest, MergingTwoBuildersGivesTheCloudOfOneThatSawBoth) {
  const Intrinsics intrinsics = Intrinsics::FromFieldOfView(160, 120, 1.0, -1.0);
  // A wall 3 m ahead with a hole (no depth) inside it: measured and filled voxels.
  cv::Mat depth(120, 160, CV_16UC1, cv::Scalar(3000));
  depth(cv::Rect(60, 40, 20, 20)).setTo(0);
  std::vector<Eigen::Isometry3d> poses(2, Eigen::Isometry3d::Identity());
  poses[1].translation() = Eigen::Vector3d(0.7, 0.1, -0.4);
  poses[1].linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  OcclusionCloudBuilder both(0.05);
  OcclusionCloudBuilder first(0.05);
  OcclusionCloudBuilder second(0.05);
  for (int i = 0; i < 2; ++i) {
    both.AddDepth(depth, intrinsics, poses[static_cast<size_t>(i)], 2, 0.3, 5.0, 20);
    (i == 0 ? first : second)
        .AddDepth(depth, intrinsics, poses[static_cast<size_t>(i)], 2, 0.3, 5.0, 20);
  }
  first.Merge(second);
  EXPECT_EQ(first.size(), both.size());
  const OcclusionCloud merged = first.Build();
  const OcclusionCloud whole = both.Build();
  ASSERT_GT(whole.world_points.size(), first.size());  // the filled voxels are in the cloud too
  EXPECT_EQ(merged.world_points, whole.world_points);
  EXPECT_THROW(first.Merge(OcclusionCloudBuilder(0.1)), Error);
}

}  // namespace
}  // namespace sightmap::identify
