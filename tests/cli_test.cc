// End-to-end tests of the `sightmap` binary: exit codes, one-line errors, and the --json keys that
// scripts depend on, checked against the real recordings.
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/test_data.h"

namespace sightmap {
namespace {

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Runs `sightmap ARGS` with no standard input; arguments are passed through the shell as written.
CommandResult Sightmap(const std::string& args) {
  const std::string dir = testing::MakeTempDir("run");
  const std::string command = std::string(SIGHTMAP_BINARY) + " " + args + " > " + dir + "/out 2> " +
                              dir + "/err < /dev/null";
  const int status = std::system(command.c_str());
  CommandResult run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  run.out = Slurp(dir + "/out");
  run.err = Slurp(dir + "/err");
  return run;
}

int CountLines(const std::string& text) {
  int lines = 0;
  for (char c : text) lines += c == '\n';
  return lines;
}

void ExpectOneLineError(const CommandResult& run, int exit_code, const std::string& fragment) {
  EXPECT_EQ(run.exit_code, exit_code) << run.err;
  EXPECT_EQ(CountLines(run.err), 1) << run.err;
  EXPECT_EQ(run.err.rfind("error: ", 0), 0u) << run.err;
  EXPECT_NE(run.err.find(fragment), std::string::npos) << run.err;
}

TEST(Cli, HelpAndVersion) {
  const CommandResult help = Sightmap("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("devices"), std::string::npos);
  EXPECT_NE(help.out.find("probe"), std::string::npos);
  const CommandResult probe_help = Sightmap("probe --help");
  EXPECT_EQ(probe_help.exit_code, 0);
  EXPECT_NE(probe_help.out.find("--json"), std::string::npos);
  EXPECT_NE(probe_help.out.find("--dump"), std::string::npos);
  const CommandResult version = Sightmap("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out.rfind("sightmap ", 0), 0u);
}

TEST(Cli, UsageErrorsExitTwo) {
  EXPECT_EQ(Sightmap("").exit_code, 2);
  ExpectOneLineError(Sightmap("frobnicate"), 2, "unknown command");
  ExpectOneLineError(Sightmap("probe"), 2, "SOURCE");
  ExpectOneLineError(Sightmap("probe x.oni --dump 3"), 2, "--out");
  ExpectOneLineError(Sightmap("probe x.oni --bogus"), 2, "--bogus");
  ExpectOneLineError(Sightmap("probe ftp://camera"), 2, "unknown SOURCE");
  ExpectOneLineError(Sightmap("devices --json extra"), 2, "extra");
}

TEST(Cli, ProbeJsonOfTheKinectRecording) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  const CommandResult run = Sightmap("probe " + path + " --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json probe = nlohmann::json::parse(run.out);
  EXPECT_EQ(probe.at("depth_frames"), 12);
  EXPECT_EQ(probe.at("color_frames"), 12);
  EXPECT_EQ(probe.at("depth_width"), 640);
  EXPECT_EQ(probe.at("depth_height"), 480);
  EXPECT_EQ(probe.at("color_width"), 640);
  EXPECT_EQ(probe.at("color_height"), 480);
  const double expected_fx = 640.0 / (2.0 * std::tan(1.0145 / 2.0));
  EXPECT_NEAR(probe.at("fx").get<double>(), expected_fx, 0.01 * expected_fx);
  EXPECT_NEAR(probe.at("fy").get<double>(), 480.0 / (2.0 * std::tan(0.7898 / 2.0)), 6.0);
  EXPECT_NEAR(probe.at("cx").get<double>(), 319.5, 1e-6);
  EXPECT_NEAR(probe.at("cy").get<double>(), 239.5, 1e-6);
  EXPECT_NEAR(probe.at("duration_s").get<double>(), 0.367, 0.01);
  EXPECT_EQ(probe.at("has_ground_truth"), false);
  EXPECT_EQ(probe.at("registration"), "device");
  EXPECT_EQ(probe.at("timestamps_increasing"), true);
}

TEST(Cli, ProbeJsonOfTheOpenNi2Recording) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/openni2-24f.oni");
  const CommandResult run = Sightmap("probe " + path + " --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json probe = nlohmann::json::parse(run.out);
  EXPECT_EQ(probe.at("depth_frames"), 24);
  EXPECT_EQ(probe.at("color_frames"), 23);
  EXPECT_EQ(probe.at("color_width"), 320);
  EXPECT_EQ(probe.at("color_height"), 240);
  EXPECT_EQ(probe.at("depth_width"), 640);
  EXPECT_EQ(probe.at("frame_width"), 320);
  EXPECT_EQ(probe.at("depth_resized_to_color"), true);
  EXPECT_EQ(probe.at("registration"), "software");
}

TEST(Cli, UnplayableRecordingsExitOneWithOneLine) {
  SIGHTMAP_REQUIRE_SHARED_DATA(legacy, "oni/legacy-v1-40f.oni");
  SIGHTMAP_REQUIRE_SHARED_DATA(header_only, "oni/header-only-0f.oni");
  ExpectOneLineError(Sightmap("probe " + legacy), 1, "ONI 1.0.0");
  ExpectOneLineError(Sightmap("probe " + header_only + " --json"), 1, "no frames");
  ExpectOneLineError(Sightmap("probe /no/such/recording.oni"), 1, "no such recording");
}

TEST(Cli, DumpPlaysBackAsA3DMatchFolder) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  const std::string dir = testing::MakeTempDir("dump");
  const CommandResult original = Sightmap("probe " + path + " --json");
  ASSERT_EQ(original.exit_code, 0) << original.err;
  const CommandResult dump = Sightmap("probe " + path + " --dump 3 --out " + dir + "/frames");
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  const CommandResult replay = Sightmap("probe 3dmatch:" + dir + "/frames --json");
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  const nlohmann::json probe = nlohmann::json::parse(replay.out);
  EXPECT_EQ(probe.at("depth_frames"), 3);
  EXPECT_EQ(probe.at("color_frames"), 3);
  // camera-intrinsics.txt carries the recording's intrinsics through the dump unchanged.
  const nlohmann::json recorded = nlohmann::json::parse(original.out);
  EXPECT_NEAR(probe.at("fx").get<double>(), recorded.at("fx").get<double>(), 1e-6);
  EXPECT_NEAR(probe.at("cy").get<double>(), recorded.at("cy").get<double>(), 1e-6);
}

TEST(Cli, ProbeJsonOfThe3DMatchFolder) {
  SIGHTMAP_REQUIRE_SHARED_DATA(dir, "rgbd/3dmatch-lounge/seq-01");
  const CommandResult run = Sightmap("probe 3dmatch:" + dir + " --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json probe = nlohmann::json::parse(run.out);
  EXPECT_EQ(probe.at("depth_frames"), 5);
  EXPECT_EQ(probe.at("color_frames"), 5);
  EXPECT_NEAR(probe.at("fx").get<double>(), 570.342205, 1e-6);
  EXPECT_NEAR(probe.at("cx").get<double>(), 320.0, 1e-6);
  EXPECT_EQ(probe.at("has_ground_truth"), true);
}

TEST(Cli, DevicesExitsZeroWithoutASensor) {
  const CommandResult text = Sightmap("devices");
  EXPECT_EQ(text.exit_code, 0) << text.err;
  const CommandResult json = Sightmap("devices --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const nlohmann::json report = nlohmann::json::parse(json.out);
  ASSERT_TRUE(report.contains("sensors"));
  EXPECT_TRUE(report.at("sensors").is_array());
  if (report.at("sensors").empty()) {
    EXPECT_NE(text.out.find("no RGB-D sensor found"), std::string::npos) << text.out;
  }
}

}  // namespace
}  // namespace sightmap
