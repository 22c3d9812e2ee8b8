#include "capture/calibration.h"

#include <fstream>

#include <gtest/gtest.h>

#include "core/check.h"
#include "tests/test_data.h"

namespace sightmap::capture {
namespace {

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(Calibration, RoundTrip) {
  const std::string dir = testing::MakeTempDir("calib");
  RgbdCalibration calibration;
  calibration.color = Intrinsics{640, 480, 525.0, 524.0, 319.5, 239.5};
  calibration.depth = Intrinsics{640, 480, 575.8, 575.8, 320.0, 240.0};
  Eigen::Isometry3d color_from_depth = Eigen::Isometry3d::Identity();
  color_from_depth.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY()).toRotationMatrix();
  color_from_depth.translation() = Eigen::Vector3d(-0.025, 0.001, 0.0);
  calibration.color_from_depth = color_from_depth;
  WriteCalibrationFile(dir + "/c.json", calibration);

  const RgbdCalibration read = ReadCalibrationFile(dir + "/c.json");
  ASSERT_TRUE(read.color && read.depth && read.color_from_depth);
  EXPECT_DOUBLE_EQ(read.color->fy, 524.0);
  EXPECT_DOUBLE_EQ(read.depth->fx, 575.8);
  EXPECT_NEAR((read.color_from_depth->matrix() - color_from_depth.matrix()).norm(), 0.0, 1e-12);
}

TEST(Calibration, PartialFileKeepsOnlyWhatItGives) {
  const std::string dir = testing::MakeTempDir("calib");
  WriteText(
      dir + "/c.json",
      R"({"color": {"width": 320, "height": 240, "fx": 260, "fy": 260, "cx": 160, "cy": 120}})");
  const RgbdCalibration read = ReadCalibrationFile(dir + "/c.json");
  ASSERT_TRUE(read.color.has_value());
  EXPECT_FALSE(read.depth.has_value());
  EXPECT_FALSE(read.color_from_depth.has_value());
}

TEST(Calibration, RejectsBadFilesWithTheirName) {
  const std::string dir = testing::MakeTempDir("calib");
  auto expect_error = [&](const std::string& text, const std::string& fragment) {
    WriteText(dir + "/bad.json", text);
    try {
      ReadCalibrationFile(dir + "/bad.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expect_error("not json", "not valid JSON");
  expect_error("{}", "has none of");
  expect_error(R"({"color": {"width": 640}})", "needs numbers");
  expect_error(R"({"color": 5})", "needs numbers");
  // Counts that no int holds, or that are not whole, are refused before any cast.
  expect_error(R"({"depth": {"width": 1e20, "height": 480, "fx": 1, "fy": 1, "cx": 0, "cy": 0}})",
               "width is out of range");
  expect_error(R"({"depth": {"width": 640, "height": -1e300, "fx": 1, "fy": 1, "cx": 0, "cy": 0}})",
               "height is out of range");
  expect_error(R"({"depth": {"width": 640.5, "height": 480, "fx": 1, "fy": 1, "cx": 0, "cy": 0}})",
               "width must be a whole number");
  expect_error(R"({"depth": {"width": 640, "height": 480, "fx": "1", "fy": 1, "cx": 0, "cy": 0}})",
               "fx must be a number");
  expect_error(R"({"color": {"width": 640, "height": 480, "fx": -1, "fy": 1, "cx": 0, "cy": 0}})",
               "focal");
  expect_error(
      R"({"color_from_depth": {"rotation": [2,0,0,0,1,0,0,0,1], "translation_m": [0,0,0]}})",
      "not a rotation");
  EXPECT_THROW(ReadCalibrationFile(dir + "/missing.json"), Error);
}

}  // namespace
}  // namespace sightmap::capture
