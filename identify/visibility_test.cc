// The see-through check's grid of view frusta, on views spread over a floor; the plane a label
// point sits on, and what lies on it seen at a grazing angle.
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

// A wall in the plane x = 0 (y along it, z up) as the walk's depth measures it: three layers of
// voxels 0-10 cm proud of it (depth noise and pose error), from y = -1 to y_end and z 0 to 2.5 m.
void AddMeasuredWall(double y_end, OcclusionCloudBuilder* builder) {
  for (double x : {0.0, 0.05, 0.10}) {
    for (double y = -1.0; y <= y_end; y += 0.02) {
      for (double z = 0.0; z <= 2.5; z += 0.02) builder->AddPoint({x, y, z});
    }
  }
}

store::LabelRecord PointLabel(const std::string& name, const Eigen::Vector3d& world) {
  store::LabelRecord label;
  label.name = name;
  label.type = "thermostat";
  store::LabelPoint point;
  point.world = world;
  label.points.push_back(point);
  return label;
}

TEST(SurfaceNormalTest, AWallGivesItsNormalACornerAndEmptySpaceNone) {
  OcclusionCloudBuilder builder(0.05);
  AddMeasuredWall(6.0, &builder);
  // A second wall across the first at y = 6: a corner, not a plane.
  for (double x = 0.0; x <= 3.0; x += 0.02) {
    for (double z = 0.0; z <= 2.5; z += 0.02) builder.AddPoint({x, 6.0, z});
  }
  const OcclusionCloud cloud = builder.Build();
  const VisibilityOptions options;
  const Eigen::Vector3d on_wall = SurfaceNormal(cloud, {0.08, 2.0, 1.5}, options);
  EXPECT_NEAR(std::abs(on_wall.x()), 1.0, 0.01) << on_wall.transpose();
  EXPECT_TRUE(SurfaceNormal(cloud, {0.1, 5.9, 1.5}, options).isZero());
  EXPECT_TRUE(SurfaceNormal(cloud, {2.0, 2.0, 1.5}, options).isZero());  // nothing within 0.3 m

  // SightLabels gives each point the normal when it has the cloud, and none without it.
  const std::vector<store::LabelRecord> labels = {PointLabel("thermostat", {0.08, 2.0, 1.5})};
  const LabelSightings with_cloud = SightLabels(labels, {}, options, &cloud);
  EXPECT_NEAR(std::abs(with_cloud[0][0].surface_normal.x()), 1.0, 0.01);
  EXPECT_TRUE(SightLabels(labels, {}, options)[0][0].surface_normal.isZero());
  VisibilityOptions off;
  off.own_surface_m = 0.0;
  EXPECT_TRUE(SightLabels(labels, {}, off, &cloud)[0][0].surface_normal.isZero());
}

TEST(OwnSurfaceTest, AThermostatSeenAlongItsWallIsNotHiddenByTheWallsThickness) {
  OcclusionCloudBuilder builder(0.05);
  AddMeasuredWall(8.0, &builder);
  const OcclusionCloud wall = builder.Build();
  const Eigen::Vector3d thermostat(0.08, 0.0, 1.5);  // on the wall, 8 cm proud of it
  const std::vector<store::LabelRecord> labels = {PointLabel("thermostat", thermostat)};
  const Intrinsics intrinsics = Intrinsics::FromFieldOfView(1280, 960, 1.1, 0.0);
  const VisibilityOptions options;
  const LabelSightings sightings = SightLabels(labels, {}, options, &wall);
  VisibilityOptions off = options;
  off.own_surface_m = 0.0;
  const auto occluded = [&](const Eigen::Isometry3d& world_from_cam, const OcclusionCloud& cloud,
                            const VisibilityOptions& with) {
    const std::vector<ApplianceInView> seen =
        AppliancesInView(labels, &cloud, intrinsics, world_from_cam, with, &sightings);
    EXPECT_EQ(seen.size(), 1u);
    return seen.empty() || seen[0].occluded;
  };
  // From 4 m along the wall and 0.4 m off it (4.6 degrees): the wall's proud voxels lie on the
  // line of sight from 0.55 m before the thermostat, farther in front than the occlusion margin
  // (0.35 m there), and within 5 cm of the thermostat's plane.
  const Eigen::Isometry3d along = LookAt({0.4, 4.0, 1.5}, thermostat, Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(occluded(along, wall, off));
  EXPECT_FALSE(occluded(along, wall, options));
  // Face on, nothing hid it either way.
  const Eigen::Isometry3d facing = LookAt({3.0, 0.0, 1.5}, thermostat, Eigen::Vector3d::UnitZ());
  EXPECT_FALSE(occluded(facing, wall, off));
  EXPECT_FALSE(occluded(facing, wall, options));
  // A cabinet's side standing out 0.5 m from the wall between them still hides it (where the line
  // of sight meets it, 0.24 m off the thermostat's plane).
  OcclusionCloudBuilder with_cabinet(0.05);
  AddMeasuredWall(8.0, &with_cabinet);
  for (double x = 0.1; x <= 0.6; x += 0.02) {
    for (double z = 0.0; z <= 2.0; z += 0.02) with_cabinet.AddPoint({x, 3.0, z});
  }
  EXPECT_TRUE(occluded(along, with_cabinet.Build(), options));
  // A camera within own_surface_m of the plane sees it edge-on: the rule does not apply.
  const Eigen::Isometry3d edge_on = LookAt({0.12, 4.0, 1.5}, thermostat, Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(occluded(edge_on, wall, options));
}

// Depth registered to the colour camera: none in the 10 columns on the right and 6 rows at the
// top, as the sensor's own bands.
cv::Mat WithUnmeasuredBands(cv::Mat depth_mm) {
  depth_mm.colRange(depth_mm.cols - 10, depth_mm.cols).setTo(0);
  depth_mm.rowRange(0, 6).setTo(0);
  return depth_mm;
}

TEST(MeasuredAreaTest, LeavesOutTheBandsAlongTheEdgesWithoutDepth) {
  cv::Mat depth = WithUnmeasuredBands(cv::Mat(120, 160, CV_16UC1, cv::Scalar(2000)));
  depth(cv::Rect(40, 30, 50, 40)).setTo(0);  // a screen: inside the measured area
  depth.at<uint16_t>(50, 155) = 1500;        // one stray measurement in the band
  EXPECT_EQ(MeasuredArea(depth), cv::Rect(0, 6, 150, 114));
  EXPECT_TRUE(MeasuredArea(cv::Mat(120, 160, CV_16UC1, cv::Scalar(0))).empty());
}

// A TV screen (no depth) on the near face of a wall (faces z = 3.0 and 3.2), seen by three
// keyframes in front of it through its hole in their depth; a fourth keyframe behind the wall
// has the point in the band along its image's right edge where registered depth has no
// measurement, the wall's far face 0.2 m before the point everywhere else.
TEST(SightLabelsTest, MissingDepthInTheBandTheSensorDoesNotMeasureIsNoSighting) {
  const Eigen::Vector3d tv(0.0, 0.0, 3.0);
  const std::vector<store::LabelRecord> labels = {PointLabel("tv", tv)};
  const Intrinsics intrinsics = Intrinsics::FromFieldOfView(160, 120, 1.0, 0.0);
  std::vector<SightingView> views;
  for (int i = 0; i < 3; ++i) {
    Eigen::Isometry3d world_from_keyframe = Eigen::Isometry3d::Identity();
    world_from_keyframe.translation() = Eigen::Vector3d(0.2 * i - 0.2, 0.1, 1.0);
    cv::Mat wall = WithUnmeasuredBands(cv::Mat(120, 160, CV_16UC1, cv::Scalar(2000)));
    wall(cv::Rect(50, 35, 60, 50)).setTo(0);  // the screen round the image's centre
    views.push_back(MakeSightingView(wall, intrinsics, world_from_keyframe, 80, 60));
  }
  Eigen::Isometry3d world_from_behind = Eigen::Isometry3d::Identity();
  world_from_behind.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  world_from_behind.translation() = Eigen::Vector3d(1.05, 0.0, 5.0);
  views.push_back(
      MakeSightingView(WithUnmeasuredBands(cv::Mat(120, 160, CV_16UC1, cv::Scalar(1800))),
                       intrinsics, world_from_behind, 80, 60));
  const Eigen::Vector2d pixel = views.back().intrinsics.Project(views.back().cam_from_world * tv);
  ASSERT_GT(pixel.x(), 75.0);  // in the band without depth (columns 75-79 of 80)
  ASSERT_LT(pixel.x(), 79.5);

  const VisibilityOptions options;
  const LabelSightings sightings = SightLabels(labels, views, options);
  EXPECT_EQ(sightings[0][0].keyframes, 3);
  EXPECT_GT(sightings[0][0].mean_ray.z(), 0.9);  // seen from the front only

  // Taken as measured, the band would count the view behind the wall as a sighting too, and the
  // point would no longer read as seen from one side.
  views.back().measured = cv::Rect();
  const LabelSightings unmeasured_taken = SightLabels(labels, views, options);
  EXPECT_EQ(unmeasured_taken[0][0].keyframes, 4);
  EXPECT_LT(unmeasured_taken[0][0].mean_ray.norm(), options.min_one_sidedness);
}

TEST(FreeStandingTest, TellsAppliancesThatStandFreeByTheLastWordOfTheirType) {
  for (const char* type :
       {"projector", "lamp", "desk lamp", "Floor_Lamp", "monitor ", "printer", "colour-printer"}) {
    EXPECT_TRUE(IsFreeStanding(type)) << type;
  }
  for (const char* type :
       {"", " ", "tv", "screen", "projector screen", "thermostat", "light_switch", "ceiling light",
        "lamp shade", "printers", "wall lamp", "Wall_Lamp"}) {
    EXPECT_FALSE(IsFreeStanding(type)) << type;
  }
}

// A box of voxels 5 cm apart, `size` wide along x, y and z, centred on `centre`.
void AddSolidBox(const Eigen::Vector3d& centre, const Eigen::Vector3d& size,
                 OcclusionCloudBuilder* builder) {
  const Eigen::Vector3d low = centre - size / 2;
  for (double x = 0.0; x <= size.x() + 1e-9; x += 0.05) {
    for (double y = 0.0; y <= size.y() + 1e-9; y += 0.05) {
      for (double z = 0.0; z <= size.z() + 1e-9; z += 0.05)
        builder->AddPoint(low + Eigen::Vector3d(x, y, z));
    }
  }
}

// A projector's body (0.35 x 0.25 x 0.1 m) hung from the ceiling, its label point at its centre,
// seen by the walk from the -x side only. From the +x side its own body stands 0.15-0.2 m in
// front of the point: nearer than the occlusion margin, farther than behind_margin_m.
TEST(FreeStandingTest, SeenFromBehindAProjectorShowsItsOwnBodyWhereAWallHungPointIsHidden) {
  const Eigen::Vector3d point(0.0, 0.0, 2.5);
  OcclusionCloudBuilder builder(0.05);
  AddSolidBox(point, {0.35, 0.25, 0.1}, &builder);
  const OcclusionCloud body = builder.Build();
  PointSighting from_one_side;
  from_one_side.mean_ray = Eigen::Vector3d::UnitX();  // keyframes looked along +x at it
  from_one_side.keyframes = 5;
  const LabelSightings sightings = {{from_one_side}};
  const Intrinsics intrinsics = Intrinsics::FromFieldOfView(1280, 960, 1.1, 0.0);
  const VisibilityOptions options;
  const auto occluded = [&](const std::string& type, const Eigen::Vector3d& eye,
                            const OcclusionCloud& cloud) {
    store::LabelRecord label = PointLabel("it", point);
    label.type = type;
    const std::vector<ApplianceInView> seen =
        AppliancesInView({label}, &cloud, intrinsics, LookAt(eye, point, Eigen::Vector3d::UnitZ()),
                         options, &sightings);
    EXPECT_EQ(seen.size(), 1u) << type;
    return seen.empty() || seen[0].occluded;
  };
  const Eigen::Vector3d behind(5.0, 0.5, 1.6);
  EXPECT_FALSE(occluded("projector", behind, body));
  EXPECT_TRUE(occluded("tv", behind, body));    // a body in front of a wall-hung point: its wall
  const Eigen::Vector3d front(-4.0, 0.5, 1.6);  // the side the walk saw it from
  EXPECT_FALSE(occluded("projector", front, body));
  EXPECT_FALSE(occluded("tv", front, body));
  // A partition 0.33 m in front of it, seen through from behind, hides it: farther than
  // free_standing_behind_margin_m, nearer than the occlusion margin at 5 m (0.40 m).
  OcclusionCloudBuilder partitioned(0.05);
  AddSolidBox(point, {0.35, 0.25, 0.1}, &partitioned);
  AddSolidBox({0.33, 0.0, 1.5}, {0.0, 3.0, 3.0}, &partitioned);
  EXPECT_TRUE(occluded("projector", behind, partitioned.Build()));
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
