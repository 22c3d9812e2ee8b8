// Round trips of every export and import: PLY (read back with ReadPly), CloudCompare label files,
// TUM trajectories.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "core/check.h"
#include "store/label_files.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/synthetic_model.h"
#include "store/trajectory.h"
#include "tests/test_data.h"

namespace sightmap::store {
namespace {

SyntheticKeyframeOptions WallKeyframes() {
  SyntheticKeyframeOptions options;
  options.width = 160;
  options.height = 120;
  options.num_features = 10;
  return options;
}

Model ThreeKeyframesOfAWall() {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  for (int i = 0; i < 3; ++i) model.AddKeyframe(MakeSyntheticKeyframe(session, i, WallKeyframes()));
  return model;
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(Ply, RoundTripThroughPcl) {
  const Model model = ThreeKeyframesOfAWall();
  const std::string path = testing::MakeTempDir("ply_roundtrip") + "/cloud.ply";
  const PlyExportStats stats = ExportPly(model, path);
  EXPECT_EQ(stats.keyframes, 3);
  // 160x120 at a pixel step of 4: 40x30 samples per keyframe.
  EXPECT_EQ(stats.back_projected_points, 3 * 40 * 30);
  EXPECT_GT(stats.written_points, 500);
  EXPECT_LT(stats.written_points, stats.back_projected_points);

  const std::string file = Slurp(path);
  const size_t header_end = file.find("end_header\n");
  ASSERT_NE(header_end, std::string::npos);
  const std::string header = file.substr(0, header_end + 11);
  // Packed little-endian records: 3 floats and 3 bytes per vertex, nothing else.
  EXPECT_EQ(file.size() - header.size(), static_cast<size_t>(stats.written_points) * 15);
  EXPECT_NE(header.find("element vertex " + std::to_string(stats.written_points) + "\n"),
            std::string::npos);
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u) << header;
  EXPECT_NE(header.find("property float x\nproperty float y\nproperty float z\n"),
            std::string::npos)
      << header;
  EXPECT_NE(header.find("property uchar red\nproperty uchar green\nproperty uchar blue\n"),
            std::string::npos)
      << header;
  EXPECT_EQ(header.find("camera"), std::string::npos) << header;

  const std::vector<ColoredPoint> points = ReadPly(path);
  ASSERT_EQ(static_cast<int64_t>(points.size()), stats.written_points);
  const Intrinsics k = SyntheticIntrinsics(160, 120);
  const double half_width_m = 2.0 * k.cx / k.fx;
  Eigen::Vector3f lo = points[0].position;
  Eigen::Vector3f hi = lo;
  int coloured = 0;
  for (const ColoredPoint& p : points) {
    lo = lo.cwiseMin(p.position);
    hi = hi.cwiseMax(p.position);
    coloured += (p.red + p.green + p.blue) > 0;
  }
  // The wall at z = 2 m, seen from cameras at x = 0, 0.1, 0.2 m.
  EXPECT_NEAR(lo.z(), 2.0, 0.011);
  EXPECT_NEAR(hi.z(), 2.0, 0.011);
  EXPECT_NEAR(lo.x(), -half_width_m, 0.05);
  EXPECT_NEAR(hi.x(), 0.2 + half_width_m * (k.width - 1 - 3 - k.cx) / k.cx, 0.05);
  EXPECT_EQ(coloured, static_cast<int>(points.size()));
}

// Found by ply_fuzzer in the PCL reader ReadPly once used: a header whose element is not "vertex",
// colour layouts it aborted the process on, a form feed in the header. Each is an error, never a
// crash.
TEST(Ply, MalformedHeadersAreErrorsNeverCrashes) {
  const std::string dir = sightmap::testing::MakeTempDir("ply");
  auto write = [&](const std::string& name, const std::string& element,
                   const std::string& first_field, size_t data_bytes) {
    std::ofstream out(dir + "/" + name, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement " << element << " 2\nproperty float "
        << first_field << "\nproperty float y\nproperty float z\nend_header\n"
        << std::string(data_bytes, '\0');
    return dir + "/" + name;
  };
  EXPECT_THROW(ReadPly(write("veruex.ply", "veruex", "x", 24)), Error);
  EXPECT_EQ(ReadPly(write("good.ply", "vertex", "x", 24)).size(), 2u);
  EXPECT_THROW(ReadPly(write("cut.ply", "vertex", "x", 12)), Error);
  EXPECT_THROW(ReadPly(write("no-x.ply", "vertex", "w", 24)), Error);
  // Red and green without blue.
  {
    std::ofstream out(dir + "/two-colours.ply", std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty "
           "float y\nproperty float z\nproperty uchar red\nproperty uchar green\nend_header\n"
        << std::string(14, '\0');
  }
  EXPECT_THROW(ReadPly(dir + "/two-colours.ply"), Error);
  // A form feed before obj_info.
  {
    std::ofstream out(dir + "/form-feed.ply", std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty "
           "float y\nproperty float z\n\fobj_info uchar red\nend_header\n"
        << std::string(12, '\0');
  }
  EXPECT_THROW(ReadPly(dir + "/form-feed.ply"), Error);
}

// Other tools write ASCII and other scalar types: read as they are, any property order.
TEST(Ply, AsciiWithDoublesAndColoursFirstIsRead) {
  const std::string path = testing::MakeTempDir("ply_ascii") + "/cloud.ply";
  std::ofstream(path) << "ply\nformat ascii 1.0\ncomment from another tool\nelement vertex 2\n"
                         "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                         "property double x\nproperty double y\nproperty double z\n"
                         "property int confidence\nend_header\n"
                         "255 128 0 1.5 -2.25 3.125 7\n1 2 3 -0.5 0 1e-3 9\n";
  const std::vector<ColoredPoint> points = ReadPly(path);
  ASSERT_EQ(points.size(), 2u);
  EXPECT_EQ(points[0].position, Eigen::Vector3f(1.5f, -2.25f, 3.125f));
  EXPECT_EQ(points[0].red, 255);
  EXPECT_EQ(points[0].green, 128);
  EXPECT_EQ(points[0].blue, 0);
  EXPECT_EQ(points[1].position, Eigen::Vector3f(-0.5f, 0.0f, 0.001f));
  EXPECT_EQ(points[1].blue, 3);
  std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                         "property float y\nproperty float z\nend_header\n1 2 3\n4 5\n";
  EXPECT_THROW(ReadPly(path), Error) << "a vertex short of a value";
}

TEST(Ply, VoxelSizeAndOutlierRemoval) {
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  KeyframeRecord keyframe = MakeSyntheticKeyframe(session, 0, WallKeyframes());
  // Three isolated depth spikes 1.5 m behind the wall.
  for (int u : {20, 80, 140}) keyframe.depth.at<uint16_t>(60, u) = 3500;
  model.AddKeyframe(keyframe);
  const std::string dir = testing::MakeTempDir("ply_filters");

  PlyExportOptions keep_all;
  keep_all.voxel_size_m = 0.0;
  EXPECT_EQ(ExportPly(model, dir + "/all.ply", keep_all).written_points, 40 * 30);
  PlyExportOptions coarse;
  coarse.voxel_size_m = 0.2;
  const int64_t coarse_points = ExportPly(model, dir + "/coarse.ply", coarse).written_points;
  // The wall seen is about 2.2 m x 1.7 m: at most 12 x 9 cells of 0.2 m, plus the spikes.
  EXPECT_LE(coarse_points, 13 * 10 + 3);
  EXPECT_GE(coarse_points, 11 * 8);

  auto count_far = [](const std::vector<ColoredPoint>& points) {
    int far = 0;
    for (const ColoredPoint& p : points) far += p.position.z() > 2.5f;
    return far;
  };
  EXPECT_EQ(count_far(ReadPly(dir + "/all.ply")), 3);
  PlyExportOptions cleaned = keep_all;
  cleaned.remove_outliers = true;
  const int64_t cleaned_points = ExportPly(model, dir + "/clean.ply", cleaned).written_points;
  EXPECT_EQ(count_far(ReadPly(dir + "/clean.ply")), 0);
  EXPECT_GE(cleaned_points, 40 * 30 - 3 - 40);  // the wall itself survives

  PlyExportOptions bad;
  bad.voxel_size_m = -1.0;
  EXPECT_THROW(ExportPly(model, dir + "/bad.ply", bad), InvalidArgument);
  EXPECT_THROW(ExportPly(model, dir + "/no/such/folder/x.ply"), Error);
  EXPECT_THROW(ExportPly(Model::Open(":memory:"), dir + "/empty.ply"), Error);
}

TEST(Ply, VoxelFilterHandlesABoundingBoxOfBillionsOfVoxels) {
  // Two walls 3 km apart at a 2 cm leaf: 150,000 x 235 x 125 voxels overflow a 32-bit index (on
  // such a cloud PCL's VoxelGrid, used before, returned its input unfiltered).
  Model model = Model::Open(":memory:");
  const SessionId session = model.BeginSession({});
  SyntheticKeyframeOptions options = WallKeyframes();
  options.step_m = 3000.0;
  KeyframeRecord near = MakeSyntheticKeyframe(session, 0, options);
  KeyframeRecord far = MakeSyntheticKeyframe(session, 1, options);
  far.world_from_cam.translation().y() = 3.0;
  far.world_from_cam.translation().z() = 2.5;
  model.AddKeyframe(near);
  model.AddKeyframe(far);
  const std::string path = testing::MakeTempDir("ply_large") + "/cloud.ply";
  PlyExportOptions coarse;
  coarse.pixel_step = 1;  // samples 1.4 cm apart on the wall: a 2 cm grid merges them
  coarse.voxel_size_m = 0.02;
  const PlyExportStats fine = ExportPly(model, path, coarse);
  EXPECT_EQ(fine.back_projected_points, 2 * 160 * 120);
  EXPECT_LT(fine.written_points, fine.back_projected_points * 3 / 4);
  coarse.voxel_size_m = 0.1;
  const PlyExportStats filtered = ExportPly(model, path, coarse);
  EXPECT_LT(filtered.written_points, fine.written_points / 4);
  EXPECT_EQ(static_cast<int64_t>(ReadPly(path).size()), filtered.written_points);
}

TEST(Ply, VoxelsMergedAcrossManyPointsMatchTheCentroidsOfOneView) {
  // The same 640x480 view four times, every pixel: 1.2M points, past the accumulator's first
  // merge. The voxels and their centroids must be those of the view exported once.
  SyntheticKeyframeOptions options;
  options.num_features = 10;
  options.step_m = 0.0;
  Model once = Model::Open(":memory:");
  Model four = Model::Open(":memory:");
  const SessionId session_once = once.BeginSession({});
  const SessionId session_four = four.BeginSession({});
  once.AddKeyframe(MakeSyntheticKeyframe(session_once, 0, options));
  for (int i = 0; i < 4; ++i) four.AddKeyframe(MakeSyntheticKeyframe(session_four, i, options));
  const std::string dir = testing::MakeTempDir("ply_merge");
  PlyExportOptions every_pixel;
  every_pixel.pixel_step = 1;
  every_pixel.voxel_size_m = 0.02;
  const PlyExportStats stats_once = ExportPly(once, dir + "/once.ply", every_pixel);
  const PlyExportStats stats_four = ExportPly(four, dir + "/four.ply", every_pixel);
  EXPECT_EQ(stats_four.back_projected_points, 4 * stats_once.back_projected_points);
  EXPECT_GT(stats_four.back_projected_points, 1'000'000);
  ASSERT_EQ(stats_four.written_points, stats_once.written_points);
  const std::vector<ColoredPoint> a = ReadPly(dir + "/once.ply");
  const std::vector<ColoredPoint> b = ReadPly(dir + "/four.ply");
  ASSERT_EQ(a.size(), b.size());
  double worst_m = 0.0;
  int colour_differences = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    worst_m = std::max(worst_m, static_cast<double>((a[i].position - b[i].position).norm()));
    colour_differences +=
        a[i].red != b[i].red || a[i].green != b[i].green || a[i].blue != b[i].blue;
  }
  EXPECT_LT(worst_m, 1e-5);
  EXPECT_EQ(colour_differences, 0);
  // Each centroid lies in its 2 cm voxel on the wall at z = 2 m.
  for (const ColoredPoint& p : a) ASSERT_NEAR(p.position.z(), 2.0, 0.011);
  EXPECT_FALSE(std::filesystem::exists(dir + "/four.ply.partial"));
}

LabelRecord MakeLabel(const std::string& name, std::vector<Eigen::Vector3d> worlds) {
  LabelRecord label;
  label.name = name;
  label.type = "lamp";
  for (const Eigen::Vector3d& world : worlds) {
    LabelPoint point;
    point.world = world;
    label.points.push_back(point);
  }
  return label;
}

TEST(LabelFiles, ExportImportRoundTrip) {
  Model source = Model::Open(":memory:");
  source.AddLabel(MakeLabel("desk lamp", {{1.25, -0.5, 2.125}}));
  source.AddLabel(MakeLabel("projector", {{0.1, 0.2, 0.3}, {-4.000001, 5.5, 6.75}}));
  const std::string dir = testing::MakeTempDir("labels_roundtrip");
  EXPECT_EQ(ExportLabels(source, dir), 2);
  ASSERT_TRUE(std::filesystem::exists(dir + "/desk lamp.txt"));
  ASSERT_TRUE(std::filesystem::exists(dir + "/projector.txt"));
  EXPECT_EQ(Slurp(dir + "/desk lamp.txt"), "1.250000 -0.500000 2.125000\n");

  Model target = Model::Open(":memory:");
  EXPECT_EQ(ImportLabels(target, dir), 2);
  const std::vector<LabelRecord> labels = target.Labels();
  ASSERT_EQ(labels.size(), 2u);
  EXPECT_EQ(labels[0].name, "desk lamp");
  EXPECT_EQ(labels[1].name, "projector");
  ASSERT_EQ(labels[1].points.size(), 2u);
  EXPECT_TRUE(labels[1].points[1].world.isApprox(Eigen::Vector3d(-4.000001, 5.5, 6.75), 1e-9));
  EXPECT_EQ(labels[1].points[1].source, LabelPointSource::kImportedFile);
  EXPECT_EQ(labels[1].points[1].file, "projector.txt");

  // Importing again replaces points instead of duplicating labels.
  WritePointList(dir + "/projector.txt", {{9, 9, 9}});
  EXPECT_EQ(ImportLabels(target, dir), 2);
  EXPECT_EQ(target.Labels().size(), 2u);
  EXPECT_EQ(target.FindLabel("projector")->points.size(), 1u);
  EXPECT_EQ(target.FindLabel("projector")->points[0].world, Eigen::Vector3d(9, 9, 9));
}

TEST(LabelFiles, ReadsCloudCompareVariants) {
  const std::string dir = testing::MakeTempDir("labels_variants");
  std::ofstream(dir + "/thermostat.txt")
      << "//X,Y,Z,R,G,B\n1.5,2,3,255,0,0\n 4 5 6 extra columns\n\n7;8;9\n-1e-1\t2\t3\r\nbad line\n";
  const std::vector<Eigen::Vector3d> points = ReadPointList(dir + "/thermostat.txt");
  ASSERT_EQ(points.size(), 4u);
  EXPECT_EQ(points[0], Eigen::Vector3d(1.5, 2, 3));
  EXPECT_EQ(points[1], Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(points[2], Eigen::Vector3d(7, 8, 9));
  EXPECT_EQ(points[3], Eigen::Vector3d(-0.1, 2, 3));

  // A line that cannot be read between two points is refused with its number, not skipped.
  std::ofstream(dir + "/gap.txt") << "# x y z\n1 2 3\n4 5 six\n// note\n7 8 9\n";
  try {
    ReadPointList(dir + "/gap.txt");
    ADD_FAILURE() << "a point was skipped";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("gap.txt:3:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("4 5 six"), std::string::npos) << e.what();
  }
  std::filesystem::remove(dir + "/gap.txt");

  // A file without points stops the import before any label is written.
  std::ofstream(dir + "/broken.txt") << "no numbers here\n";
  Model model = Model::Open(":memory:");
  EXPECT_THROW(ImportLabels(model, dir), Error);
  EXPECT_TRUE(model.Labels().empty());
  EXPECT_EQ(LabelFileName("a/b\\c"), "a_b_c.txt");
}

TEST(Trajectory, TumRoundTripIsExactInTime) {
  std::vector<StampedPose> poses;
  for (int i = 0; i < 5; ++i) {
    StampedPose pose;
    pose.timestamp_ns = 1305031102175304123LL + i * 33333333LL;
    pose.world_from_cam.linear() =
        Eigen::AngleAxisd(0.4 * i, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    pose.world_from_cam.translation() = Eigen::Vector3d(0.1 * i, -2.5, 1e-3 * i);
    poses.push_back(pose);
  }
  const std::string path = testing::MakeTempDir("trajectory") + "/poses.txt";
  WriteTumTrajectory(path, poses);
  const std::vector<StampedPose> read = ReadTumTrajectory(path);
  ASSERT_EQ(read.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(read[i].timestamp_ns, poses[i].timestamp_ns);
    EXPECT_TRUE(read[i].world_from_cam.isApprox(poses[i].world_from_cam, 1e-9));
  }
  std::ofstream(path) << "# ground truth\n1305031102.1753 1 2 3 0 0 0 1\n1.5e0 0 0 0 0 0 1 0\n";
  const std::vector<StampedPose> tum = ReadTumTrajectory(path);
  ASSERT_EQ(tum.size(), 2u);
  EXPECT_EQ(tum[0].timestamp_ns, 1305031102175300000LL);
  EXPECT_EQ(tum[1].timestamp_ns, 1500000000LL);
  EXPECT_NEAR(tum[1].world_from_cam.linear()(0, 0), -1.0, 1e-12);  // 180 deg about y
  std::ofstream(path) << "1.0 1 2 3\n";
  EXPECT_THROW(ReadTumTrajectory(path), Error);
}

TEST(Trajectory, ModelTrajectoryUsesOptimisedOrOdometryPoses) {
  Model model = ThreeKeyframesOfAWall();
  const std::vector<KeyframeInfo> keyframes = model.Keyframes();
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.translation() = Eigen::Vector3d(7, 8, 9);
  model.UpdatePoses({{keyframes[1].id, moved}});
  const std::vector<StampedPose> optimised = ModelTrajectory(model);
  ASSERT_EQ(optimised.size(), 3u);
  EXPECT_EQ(optimised[1].timestamp_ns, 1000000000);
  EXPECT_TRUE(optimised[1].world_from_cam.isApprox(moved));
  EXPECT_NEAR(ModelTrajectory(model, true)[1].world_from_cam.translation().x(), 0.1, 1e-12);
}

}  // namespace
}  // namespace sightmap::store
