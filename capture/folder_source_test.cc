#include "capture/folder_source.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/calibration.h"
#include "core/check.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "tests/test_data.h"

namespace sightmap::capture {
namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------------------------------------------
// Shared 3DMatch frames

Eigen::Matrix4d ReadMatrix4(const std::string& path) {
  std::ifstream in(path);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) in >> m(r, c);
  }
  EXPECT_TRUE(in) << path;
  return m;
}

double AngleDegrees(const Eigen::Matrix3d& rotation) {
  return RadToDeg(Eigen::AngleAxisd(rotation).angle());
}

TEST(ThreeDMatchFolderTest, ReadsTheSharedLoungeFrames) {
  SIGHTMAP_REQUIRE_SHARED_DATA(dir, "rgbd/3dmatch-lounge/seq-01");
  std::unique_ptr<RgbdSource> source = OpenThreeDMatchFolder(dir, SourceOptions());

  const SourceMetadata& metadata = source->metadata();
  EXPECT_EQ(metadata.kind, "3dmatch");
  EXPECT_EQ(metadata.uri, dir);
  EXPECT_EQ(metadata.registration, DepthRegistration::kSource);
  EXPECT_EQ(metadata.color_width, 640);
  EXPECT_EQ(metadata.color_height, 480);
  EXPECT_EQ(metadata.depth_width, 640);
  EXPECT_EQ(metadata.depth_height, 480);
  EXPECT_EQ(metadata.intrinsics.width, 640);
  EXPECT_EQ(metadata.intrinsics.height, 480);
  EXPECT_NEAR(metadata.intrinsics.fx, 570.342205, 1e-6);
  EXPECT_NEAR(metadata.intrinsics.fy, 570.342205, 1e-6);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.cx, 320.0);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.cy, 240.0);
  EXPECT_EQ(metadata.intrinsics_origin, "camera-intrinsics.txt");
  EXPECT_EQ(metadata.depth_frame_count, 5);
  EXPECT_EQ(metadata.color_frame_count, 5);
  EXPECT_TRUE(metadata.has_ground_truth);
  EXPECT_DOUBLE_EQ(metadata.nominal_fps, 30.0);
  EXPECT_FALSE(metadata.notes.empty());

  const std::vector<int64_t> numbers = {0, 1, 2, 116, 422};
  std::vector<RgbdFrame> frames;
  while (std::optional<RgbdFrame> frame = source->Next()) frames.push_back(std::move(*frame));
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_FALSE(source->Next().has_value());
  EXPECT_FALSE(source->Next().has_value());

  for (size_t i = 0; i < frames.size(); ++i) {
    const RgbdFrame& frame = frames[i];
    SCOPED_TRACE(numbers[i]);
    EXPECT_EQ(frame.index, static_cast<int64_t>(i));
    EXPECT_EQ(frame.timestamp_ns, numbers[i] * 33'333'333);
    if (i > 0) {
      EXPECT_GT(frame.timestamp_ns, frames[i - 1].timestamp_ns);
    }
    EXPECT_EQ(frame.color.type(), CV_8UC3);
    EXPECT_EQ(frame.depth.type(), CV_16UC1);
    EXPECT_EQ(frame.color.cols, 640);
    EXPECT_EQ(frame.color.rows, 480);
    EXPECT_EQ(frame.depth.size(), frame.color.size());
    EXPECT_GT(ValidDepthFraction(frame.depth), 0.5);
    // Indoor Kinect depth: between 0.3 m and 10 m where measured.
    double min_mm = 0.0;
    double max_mm = 0.0;
    cv::minMaxLoc(frame.depth, &min_mm, &max_mm, nullptr, nullptr, frame.depth > 0);
    EXPECT_GE(min_mm, 300.0);
    EXPECT_LE(max_mm, 10000.0);

    ASSERT_TRUE(frame.world_from_cam_gt.has_value());
    char name[64];
    std::snprintf(name, sizeof(name), "frame-%06lld.pose.txt", static_cast<long long>(numbers[i]));
    const Eigen::Matrix4d expected = ReadMatrix4((fs::path(dir) / name).string());
    EXPECT_LT((frame.world_from_cam_gt->matrix() - expected).cwiseAbs().maxCoeff(), 1e-5);
  }

  const auto relative = [&frames](size_t a, size_t b) {
    return Eigen::Isometry3d(frames[a].world_from_cam_gt->inverse() * *frames[b].world_from_cam_gt);
  };
  EXPECT_NEAR(relative(0, 1).translation().norm(), 0.015, 0.001);
  EXPECT_NEAR(AngleDegrees(relative(0, 1).linear()), 0.4, 0.1);
  EXPECT_NEAR(relative(0, 2).translation().norm(), 0.031, 0.001);
  EXPECT_NEAR(relative(0, 3).translation().norm(), 0.476, 0.001);
  EXPECT_NEAR(AngleDegrees(relative(0, 3).linear()), 32.1, 0.1);
  EXPECT_NEAR(relative(3, 4).translation().norm(), 1.14, 0.005);
  EXPECT_NEAR(AngleDegrees(relative(3, 4).linear()), 14.9, 0.1);

  const SourceStats stats = source->stats();
  EXPECT_EQ(stats.depth_frames, 5);
  EXPECT_EQ(stats.color_frames, 5);
  EXPECT_EQ(stats.paired_frames, 5);
  EXPECT_EQ(stats.unpaired_frames, 0);
}

// What `probe --dump` writes plays back as the same frames: pixels, depth, pose and intrinsics.
TEST(ThreeDMatchFolderTest, WrittenFramesReadBackExactly) {
  const std::string dir = testing::MakeTempDir("3dmatch-written");
  const Intrinsics k = Intrinsics::FromPinhole(64, 48, 57.123456789, 58.5, 31.25, 23.75);
  std::vector<RgbdFrame> frames(3);
  for (int i = 0; i < 3; ++i) {
    RgbdFrame& frame = frames[static_cast<size_t>(i)];
    frame.index = i * 2;  // gaps are allowed
    frame.color = cv::Mat(48, 64, CV_8UC3);
    cv::randu(frame.color, cv::Scalar::all(0), cv::Scalar::all(255));
    frame.depth = cv::Mat(48, 64, CV_16UC1);
    cv::randu(frame.depth, cv::Scalar(0), cv::Scalar(8000));
    if (i != 1) {
      frame.world_from_cam_gt = Eigen::Translation3d(0.1 * i, -1.25, 2.0 / 3.0) *
                                Eigen::AngleAxisd(0.3 * i + 0.1, Eigen::Vector3d::UnitY());
    }
    WriteThreeDMatchFrame(dir, frame);
  }
  WriteThreeDMatchIntrinsics(dir, k);
  const std::unique_ptr<RgbdSource> source = OpenThreeDMatchFolder(dir, SourceOptions());
  EXPECT_NEAR(source->metadata().intrinsics.fx, k.fx, 1e-12);
  EXPECT_NEAR(source->metadata().intrinsics.cy, k.cy, 1e-12);
  for (const RgbdFrame& written : frames) {
    const std::optional<RgbdFrame> read = source->Next();
    ASSERT_TRUE(read);
    EXPECT_EQ(cv::norm(read->color, written.color, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(read->depth, written.depth, cv::NORM_INF), 0.0);
    ASSERT_EQ(read->world_from_cam_gt.has_value(), written.world_from_cam_gt.has_value());
    if (written.world_from_cam_gt) {
      EXPECT_LT((read->world_from_cam_gt->matrix() - written.world_from_cam_gt->matrix())
                    .cwiseAbs()
                    .maxCoeff(),
                1e-15);
    }
  }
  EXPECT_FALSE(source->Next());
  EXPECT_THROW(WriteThreeDMatchFrame(dir + "/missing", frames[0]), Error);
}

TEST(ThreeDMatchFolderTest, SceneFolderWithOneSequenceReadsIt) {
  SIGHTMAP_REQUIRE_SHARED_DATA(dir, "rgbd/3dmatch-lounge");
  std::unique_ptr<RgbdSource> source = OpenThreeDMatchFolder(dir, SourceOptions());
  EXPECT_EQ(source->metadata().depth_frame_count, 5);
  EXPECT_NEAR(source->metadata().intrinsics.fx, 570.342205, 1e-6);
}

// ------------------------------------------------------------------------------------------------
// Synthetic 3DMatch folder

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

void WriteThreeDMatchFrame(const fs::path& dir, int number, uint16_t depth_mm,
                           const std::string& pose) {
  char prefix[32];
  std::snprintf(prefix, sizeof(prefix), "frame-%06d", number);
  const fs::path base = dir / prefix;
  ASSERT_TRUE(cv::imwrite(base.string() + ".color.png",
                          cv::Mat(24, 32, CV_8UC3, cv::Scalar(number, 50, 100))));
  cv::Mat depth(24, 32, CV_16UC1, cv::Scalar(depth_mm));
  depth.at<uint16_t>(0, 0) = 65535;
  depth.at<uint16_t>(0, 1) = 0;
  ASSERT_TRUE(cv::imwrite(base.string() + ".depth.png", depth));
  if (!pose.empty()) WriteText(base.string() + ".pose.txt", pose);
}

TEST(ThreeDMatchFolderTest, SyntheticFolderWithGapsMissingPosesAndNoDepthMarkers) {
  const fs::path scene = testing::MakeTempDir("scene");
  const fs::path dir = scene / "seq-03";
  fs::create_directories(dir);
  WriteText(scene / "camera-intrinsics.txt", "60 0 15.5\n0 61 11.5\n0 0 1\n");
  const std::string identity_with_x = "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  WriteThreeDMatchFrame(dir, 7, 1200, identity_with_x);
  // 3DMatch marks frames without a pose with non-finite matrices.
  WriteThreeDMatchFrame(dir, 3, 1100, "");
  WriteText(dir / "frame-000003.pose.txt",
            "-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n");
  WriteThreeDMatchFrame(dir, 12, 1300, "");
  // A colour image without its depth image is skipped.
  ASSERT_TRUE(cv::imwrite((dir / "frame-000020.color.png").string(),
                          cv::Mat(24, 32, CV_8UC3, cv::Scalar(1, 2, 3))));

  // The scene folder holds one sequence, so it reads that one.
  std::unique_ptr<RgbdSource> source = OpenThreeDMatchFolder(scene.string(), SourceOptions());
  const SourceMetadata& metadata = source->metadata();
  EXPECT_EQ(metadata.color_width, 32);
  EXPECT_EQ(metadata.color_height, 24);
  EXPECT_EQ(metadata.intrinsics.width, 32);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.fx, 60.0);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.fy, 61.0);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.cx, 15.5);
  EXPECT_DOUBLE_EQ(metadata.intrinsics.cy, 11.5);
  EXPECT_EQ(metadata.depth_frame_count, 3);
  EXPECT_TRUE(metadata.has_ground_truth);  // on frame 7 only
  EXPECT_EQ(source->stats().unpaired_frames, 1);

  const std::vector<int> numbers = {3, 7, 12};
  const std::vector<uint16_t> depths = {1100, 1200, 1300};
  for (size_t i = 0; i < numbers.size(); ++i) {
    SCOPED_TRACE(numbers[i]);
    std::optional<RgbdFrame> frame = source->Next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->index, static_cast<int64_t>(i));
    EXPECT_EQ(frame->timestamp_ns, numbers[i] * int64_t{33'333'333});
    EXPECT_EQ(frame->color.at<cv::Vec3b>(5, 5),
              cv::Vec3b(static_cast<uint8_t>(numbers[i]), 50, 100));
    EXPECT_EQ(frame->depth.at<uint16_t>(5, 5), depths[i]);
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 0), 0);  // 65535 = no measurement
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 1), 0);
    EXPECT_EQ(frame->world_from_cam_gt.has_value(), numbers[i] == 7);
  }
  EXPECT_FALSE(source->Next().has_value());
  EXPECT_FALSE(source->Next().has_value());

  // Without camera-intrinsics.txt the folder cannot be used.
  fs::remove(scene / "camera-intrinsics.txt");
  try {
    OpenThreeDMatchFolder(dir.string(), SourceOptions());
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("camera-intrinsics.txt"), std::string::npos) << e.what();
  }
}

TEST(ThreeDMatchFolderTest, SceneFolderWithSeveralSequencesAsksForOne) {
  const fs::path scene = testing::MakeTempDir("scene");
  WriteText(scene / "camera-intrinsics.txt", "60 0 15.5\n0 61 11.5\n0 0 1\n");
  for (const char* seq : {"seq-01", "seq-02"}) {
    fs::create_directories(scene / seq);
    WriteThreeDMatchFrame(scene / seq, 0, 1000, "");
  }
  try {
    OpenThreeDMatchFolder(scene.string(), SourceOptions());
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("seq-01, seq-02"), std::string::npos) << e.what();
  }
}

// ------------------------------------------------------------------------------------------------
// Synthetic TUM folder

constexpr int64_t kBaseNs = 1'305'031'102'100'000'000;  // 1305031102.100000 s
constexpr int kWidth = 64;
constexpr int kHeight = 48;

// Seconds after kBaseNs, formatted as TUM does (6 decimals).
std::string TumTime(double offset_s) {
  std::ostringstream out;
  out << "1305031102." << std::setw(6) << std::setfill('0')
      << static_cast<long long>(std::llround((0.1 + offset_s) * 1e6));
  return out.str();
}

int64_t TumTimeNs(double offset_s) {
  return kBaseNs - 100'000'000 + std::llround((0.1 + offset_s) * 1e6) * 1000;
}

// The ground-truth trajectory: linear translation, constant-rate turn about z, so interpolation
// between samples reproduces it exactly.
Eigen::Isometry3d TruePose(double t) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(1.0 * t, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(0.5 * t, -0.2 * t, 1.0 + 0.1 * t);
  return pose;
}

cv::Scalar ColorOf(int id) { return cv::Scalar(30 + 10 * id, 7 * id, 255 - id); }

struct TumFolderOptions {
  bool depth_8bit_in_frame_2 = false;
  bool all_depth_8bit = false;
  bool colour_64x32_in_frame_1 = false;
};

// Depth times d0..d5 at 30 Hz (d4 has no colour partner); colour frames jittered around them, plus
// a decoy 15 ms after d1 that loses to closer frames and a straggler 60 ms after d5.
const std::vector<double> kDepthOffsets = {0.0, 0.033333, 0.066667, 0.1, 0.133333, 0.166667};
struct ColourEntry {
  double offset;
  int id;
};
const std::vector<ColourEntry> kColours = {{0.004, 0}, {0.026333, 1}, {0.048333, 9}, {0.078667, 2},
                                           {0.097, 3}, {0.175667, 5}, {0.226667, 8}};

fs::path WriteTumFolder(const std::string& name, const TumFolderOptions& options) {
  const fs::path dir = testing::MakeTempDir(name);
  fs::create_directories(dir / "rgb");
  fs::create_directories(dir / "depth");
  std::ostringstream rgb_list;
  rgb_list << "# color images\n# file: 'synthetic'\n# timestamp filename\n";
  for (const ColourEntry& colour : kColours) {
    const std::string file = "rgb/" + TumTime(colour.offset) + ".png";
    const int width = options.colour_64x32_in_frame_1 && colour.id == 1 ? 32 : kWidth;
    EXPECT_TRUE(
        cv::imwrite((dir / file).string(), cv::Mat(kHeight, width, CV_8UC3, ColorOf(colour.id))));
    rgb_list << TumTime(colour.offset) << " " << file << "\n";
  }
  std::ostringstream depth_list;
  depth_list << "# depth maps\n# file: 'synthetic'\n# timestamp filename\n";
  for (size_t k = 0; k < kDepthOffsets.size(); ++k) {
    const std::string file = "depth/" + TumTime(kDepthOffsets[k]) + ".png";
    cv::Mat depth(kHeight, kWidth, CV_16UC1, cv::Scalar(5000 + 500 * static_cast<int>(k)));
    depth.at<uint16_t>(0, 0) = 0;
    depth.at<uint16_t>(0, 1) = 7;      // 1.4 mm -> 1
    depth.at<uint16_t>(0, 2) = 8;      // 1.6 mm -> 2
    depth.at<uint16_t>(0, 3) = 65535;  // 13107 mm
    if (options.all_depth_8bit || (options.depth_8bit_in_frame_2 && k == 2)) {
      depth = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(200));
    }
    EXPECT_TRUE(cv::imwrite((dir / file).string(), depth));
    depth_list << TumTime(kDepthOffsets[k]) << " " << file << "\n";
  }
  // 100 Hz mocap from -50 ms to +120 ms, then a drop-out until +300 ms.
  std::ostringstream ground_truth;
  ground_truth << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
               << std::setprecision(12);
  for (int i = -5; i <= 40; ++i) {
    if (i > 12 && i < 30) continue;
    const double t = 0.01 * i;
    const Eigen::Isometry3d pose = TruePose(t);
    const Eigen::Quaterniond q(pose.linear());
    ground_truth << TumTime(t) << " " << pose.translation().x() << " " << pose.translation().y()
                 << " " << pose.translation().z() << " " << q.x() << " " << q.y() << " " << q.z()
                 << " " << q.w() << "\n";
  }
  WriteText(dir / "rgb.txt", rgb_list.str());
  WriteText(dir / "depth.txt", depth_list.str());
  WriteText(dir / "groundtruth.txt", ground_truth.str());
  return dir;
}

TEST(TumFolderTest, AssociatesConvertsDepthAndInterpolatesGroundTruth) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), SourceOptions());

  const SourceMetadata& metadata = source->metadata();
  EXPECT_EQ(metadata.kind, "tum");
  EXPECT_EQ(metadata.uri, dir.string());
  EXPECT_EQ(metadata.registration, DepthRegistration::kSource);
  EXPECT_EQ(metadata.color_width, kWidth);
  EXPECT_EQ(metadata.color_height, kHeight);
  EXPECT_EQ(metadata.depth_width, kWidth);
  EXPECT_EQ(metadata.depth_height, kHeight);
  // The 640x480 TUM ROS default scaled by 1/10.
  EXPECT_EQ(metadata.intrinsics.width, kWidth);
  EXPECT_EQ(metadata.intrinsics.height, kHeight);
  EXPECT_NEAR(metadata.intrinsics.fx, 52.5, 1e-9);
  EXPECT_NEAR(metadata.intrinsics.fy, 52.5, 1e-9);
  EXPECT_NEAR(metadata.intrinsics.cx, 31.5, 1e-9);
  EXPECT_NEAR(metadata.intrinsics.cy, 23.5, 1e-9);
  EXPECT_EQ(metadata.intrinsics_origin, "default (TUM ROS)");
  EXPECT_EQ(metadata.depth_frame_count, 5);
  EXPECT_EQ(metadata.color_frame_count, 5);
  EXPECT_TRUE(metadata.has_ground_truth);
  EXPECT_NEAR(metadata.nominal_fps, 30.0, 0.01);
  bool intrinsics_note = false;
  for (const std::string& note : metadata.notes) {
    intrinsics_note |=
        note.find("525") != std::string::npos && note.find("--calib") != std::string::npos;
  }
  EXPECT_TRUE(intrinsics_note);

  // One depth frame (d4) and two colour frames (decoy, straggler) have no partner.
  EXPECT_EQ(source->stats().unpaired_frames, 3);

  const std::vector<size_t> depth_of_frame = {0, 1, 2, 3, 5};
  const std::vector<int> colour_of_frame = {0, 1, 2, 3, 5};
  for (size_t i = 0; i < depth_of_frame.size(); ++i) {
    SCOPED_TRACE(i);
    std::optional<RgbdFrame> frame = source->Next();
    ASSERT_TRUE(frame.has_value());
    const size_t k = depth_of_frame[i];
    EXPECT_EQ(frame->index, static_cast<int64_t>(i));
    EXPECT_EQ(frame->timestamp_ns, TumTimeNs(kDepthOffsets[k]));
    ASSERT_EQ(frame->color.type(), CV_8UC3);
    ASSERT_EQ(frame->depth.type(), CV_16UC1);
    EXPECT_EQ(frame->color.size(), cv::Size(kWidth, kHeight));
    EXPECT_EQ(frame->depth.size(), cv::Size(kWidth, kHeight));
    const cv::Scalar colour = ColorOf(colour_of_frame[i]);
    EXPECT_EQ(frame->color.at<cv::Vec3b>(10, 10),
              cv::Vec3b(static_cast<uint8_t>(colour[0]), static_cast<uint8_t>(colour[1]),
                        static_cast<uint8_t>(colour[2])));
    EXPECT_EQ(frame->depth.at<uint16_t>(10, 10), 1000 + 100 * k);
    EXPECT_DOUBLE_EQ(frame->DepthMeters(10, 10), 1.0 + 0.1 * static_cast<double>(k));
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 0), 0);
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 1), 1);
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 2), 2);
    EXPECT_EQ(frame->depth.at<uint16_t>(0, 3), 13107);

    if (k == 5) {
      // d5 lies in the 180 ms mocap drop-out: no ground truth.
      EXPECT_FALSE(frame->world_from_cam_gt.has_value());
    } else {
      ASSERT_TRUE(frame->world_from_cam_gt.has_value());
      const Eigen::Isometry3d expected = TruePose(kDepthOffsets[k]);
      EXPECT_LT((frame->world_from_cam_gt->translation() - expected.translation()).norm(), 1e-9);
      EXPECT_LT(
          Eigen::AngleAxisd(frame->world_from_cam_gt->linear().transpose() * expected.linear())
              .angle(),
          1e-9);
    }
  }
  EXPECT_FALSE(source->Next().has_value());
  EXPECT_FALSE(source->Next().has_value());

  const SourceStats stats = source->stats();
  EXPECT_EQ(stats.depth_frames, 5);
  EXPECT_EQ(stats.color_frames, 5);
  EXPECT_EQ(stats.paired_frames, 5);
  EXPECT_EQ(stats.unpaired_frames, 3);
}

TEST(TumFolderTest, TighterToleranceDropsJitteredPairs) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  SourceOptions options;
  options.sync_tolerance_ns = 5'000'000;  // keeps d0 (+4 ms) and d3 (-3 ms) only
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), options);
  EXPECT_EQ(source->metadata().depth_frame_count, 2);
  EXPECT_EQ(source->stats().unpaired_frames, (6 - 2) + (7 - 2));
  std::optional<RgbdFrame> first = source->Next();
  std::optional<RgbdFrame> second = source->Next();
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->timestamp_ns, TumTimeNs(0.0));
  EXPECT_EQ(second->timestamp_ns, TumTimeNs(0.1));
  EXPECT_EQ(second->depth.at<uint16_t>(10, 10), 1300);
}

TEST(TumFolderTest, CalibrationFileReplacesDefaultIntrinsics) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  RgbdCalibration calibration;
  calibration.color = Intrinsics{640, 480, 600.0, 610.0, 320.0, 240.0};
  const std::string calibration_file = (dir / "calib.json").string();
  WriteCalibrationFile(calibration_file, calibration);
  SourceOptions options;
  options.calibration_file = calibration_file;
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), options);
  const Intrinsics& k = source->metadata().intrinsics;
  EXPECT_EQ(source->metadata().intrinsics_origin, "calibration-file");
  EXPECT_EQ(k.width, kWidth);
  EXPECT_EQ(k.height, kHeight);
  EXPECT_NEAR(k.fx, 60.0, 1e-9);
  EXPECT_NEAR(k.fy, 61.0, 1e-9);
  EXPECT_NEAR(k.cx, 31.55, 1e-9);
  EXPECT_NEAR(k.cy, 23.55, 1e-9);
}

TEST(TumFolderTest, RealtimeKeepsTheRecordedPace) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  SourceOptions options;
  options.realtime = true;
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), options);
  const auto start = std::chrono::steady_clock::now();
  int frames = 0;
  while (source->Next()) ++frames;
  const double elapsed_s = SecondsSince(start);
  EXPECT_EQ(frames, 5);
  EXPECT_GE(elapsed_s, 0.166);  // d0 to d5
}

// ------------------------------------------------------------------------------------------------
// Errors

// Runs `open` and returns the Error's message, or "" (with a failure) when nothing was thrown.
template <typename Fn>
std::string ErrorMessage(Fn&& open) {
  try {
    open();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected sightmap::Error";
  return "";
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(FolderSourceErrorTest, MissingFolder) {
  const std::string missing = testing::MakeTempDir("x") + "/does-not-exist";
  const std::string tum = ErrorMessage([&] { OpenTumFolder(missing, SourceOptions()); });
  EXPECT_TRUE(Contains(tum, missing) && Contains(tum, "does not exist")) << tum;
  const std::string match = ErrorMessage([&] { OpenThreeDMatchFolder(missing, SourceOptions()); });
  EXPECT_TRUE(Contains(match, missing) && Contains(match, "does not exist")) << match;
}

TEST(FolderSourceErrorTest, FolderWithoutRgbTxt) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  fs::remove(dir / "rgb.txt");
  const std::string message = ErrorMessage([&] { OpenTumFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, "has no rgb.txt")) << message;
}

TEST(FolderSourceErrorTest, FolderWithoutFrames) {
  const fs::path dir = testing::MakeTempDir("tum");
  WriteText(dir / "rgb.txt", "# nothing\n");
  WriteText(dir / "depth.txt", "# nothing\n");
  const std::string message = ErrorMessage([&] { OpenTumFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, "lists 0 colour and 0 depth frames")) << message;

  const std::string empty =
      ErrorMessage([&] { OpenThreeDMatchFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(empty, "frame-NNNNNN")) << empty;
}

TEST(FolderSourceErrorTest, MalformedLinesNameFileAndLine) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  WriteText(dir / "rgb.txt", "# timestamp filename\n1305031102.1 rgb/a.png\nabc rgb/b.png\n");
  std::string message = ErrorMessage([&] { OpenTumFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, (dir / "rgb.txt").string() + ":3:")) << message;

  const fs::path dir2 = WriteTumFolder("tum2", TumFolderOptions());
  std::ofstream(dir2 / "groundtruth.txt", std::ios::app) << "1305031102.5 1 2 3 0 0 0\n";
  message = ErrorMessage([&] { OpenTumFolder(dir2.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, "groundtruth.txt:")) << message;
}

TEST(FolderSourceErrorTest, ListedImageMissing) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  fs::remove(dir / "depth" / (TumTime(kDepthOffsets[1]) + ".png"));
  const std::string message = ErrorMessage([&] { OpenTumFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, "depth.txt:5") && Contains(message, "does not exist")) << message;
}

TEST(FolderSourceErrorTest, EightBitDepth) {
  // Caught from the header when the first frame is 8-bit...
  const fs::path dir = WriteTumFolder("all", {false, true, false});
  std::string message = ErrorMessage([&] { OpenTumFolder(dir.string(), SourceOptions()); });
  EXPECT_TRUE(Contains(message, "8-bit with 1 channel") && Contains(message, "16-bit")) << message;

  // ...and when a later frame is read.
  const fs::path dir2 = WriteTumFolder("third", {true, false, false});
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir2.string(), SourceOptions());
  ASSERT_TRUE(source->Next().has_value());
  ASSERT_TRUE(source->Next().has_value());
  message = ErrorMessage([&] { source->Next(); });
  EXPECT_TRUE(Contains(message, "8-bit with 1 channel")) << message;
}

TEST(FolderSourceErrorTest, ColourAndDepthOfDifferentSize) {
  const fs::path dir = WriteTumFolder("tum", {false, false, true});
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), SourceOptions());
  ASSERT_TRUE(source->Next().has_value());
  const std::string message = ErrorMessage([&] { source->Next(); });
  EXPECT_TRUE(Contains(message, "64x48") && Contains(message, "32x48")) << message;
}

TEST(FolderSourceErrorTest, UnreadableImage) {
  const fs::path dir = WriteTumFolder("tum", TumFolderOptions());
  WriteText(dir / "rgb" / (TumTime(kColours[1].offset) + ".png"), "not a png");
  std::unique_ptr<RgbdSource> source = OpenTumFolder(dir.string(), SourceOptions());
  ASSERT_TRUE(source->Next().has_value());
  const std::string message = ErrorMessage([&] { source->Next(); });
  EXPECT_TRUE(Contains(message, "cannot read the colour image")) << message;
}

}  // namespace
}  // namespace sightmap::capture
