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

#include "store/label_files.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/synthetic_model.h"
#include "store/trajectory.h"
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

// A small model as mapping would leave it: two sessions, four keyframes in two segments joined by
// nothing, one loop closure inside the first, two labels.
std::string MakeSmallModel(const std::string& name) {
  const std::string path = testing::MakeTempDir(name) + "/model.db";
  Model model = Model::Open(path);
  SyntheticKeyframeOptions options;
  options.width = 160;
  options.height = 120;
  options.num_features = 20;
  std::vector<KeyframeId> ids;
  for (int session_index = 0; session_index < 2; ++session_index) {
    const SessionId session = model.BeginSession({});
    for (int i = 0; i < 2; ++i) {
      KeyframeRecord keyframe = MakeSyntheticKeyframe(session, session_index * 2 + i, options);
      if (i > 0) {
        LinkRecord odometry;
        odometry.from = ids.back();
        keyframe.links.push_back(odometry);
      }
      ids.push_back(model.AddKeyframe(keyframe));
    }
    model.EndSession(session, SessionEnd::kFinished, 1);
  }
  LinkRecord loop;
  loop.from = ids[1];
  loop.to = ids[0];
  loop.type = LinkType::kLoopClosure;
  model.AddLink(loop);
  for (const char* name_of_label : {"lamp", "projector"}) {
    LabelRecord label;
    label.name = name_of_label;
    LabelPoint point;
    point.world = Eigen::Vector3d(1.0, 0.5, 2.0);
    label.points.push_back(point);
    model.AddLabel(label);
  }
  return path;
}

TEST(Cli, InfoJsonKeysOfASmallModel) {
  const std::string path = MakeSmallModel("cli_info");
  const CommandResult run = Sightmap("info " + path + " --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json info = nlohmann::json::parse(run.out);
  EXPECT_EQ(info.at("sessions"), 2);
  EXPECT_EQ(info.at("keyframes"), 4);
  EXPECT_EQ(info.at("loop_closures"), 1);
  EXPECT_EQ(info.at("segments"), 2);
  EXPECT_EQ(info.at("labels"), 2);
  EXPECT_EQ(info.at("schema_version"), Model::LatestSchemaVersion());
  EXPECT_GT(info.at("size_bytes").get<int64_t>(), 10000);
  EXPECT_EQ(info.at("links").at("odometry"), 2);
  EXPECT_NEAR(info.at("bounding_box").at("max")[0].get<double>(), 1.0, 1e-9);
  const CommandResult text = Sightmap("info " + path);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("keyframes      4 in 2 segment(s)"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("lamp, projector"), std::string::npos) << text.out;
}

TEST(Cli, ExportWritesPlyTrajectoryAndLabels) {
  const std::string path = MakeSmallModel("cli_export");
  const std::string out = testing::MakeTempDir("cli_export_out");
  const CommandResult run =
      Sightmap("export " + path + " --ply " + out + "/cloud.ply --voxel 0.05" + " --trajectory " +
               out + "/poses.txt --labels " + out + "/labels");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(run.err.empty()) << run.err;
  const std::vector<ColoredPoint> cloud = ReadPly(out + "/cloud.ply");
  EXPECT_GT(cloud.size(), 100u);
  EXPECT_NE(run.out.find(std::to_string(cloud.size()) + " points from 4 keyframes"),
            std::string::npos)
      << run.out;
  const std::vector<StampedPose> poses = ReadTumTrajectory(out + "/poses.txt");
  ASSERT_EQ(poses.size(), 4u);
  EXPECT_EQ(poses[3].timestamp_ns, 3000000000);
  EXPECT_NEAR(poses[3].world_from_cam.translation().x(), 0.3, 1e-9);
  EXPECT_EQ(ReadPointList(out + "/labels/projector.txt").size(), 1u);
  EXPECT_TRUE(std::ifstream(out + "/labels/lamp.txt").good());
  // A coarser voxel gives fewer points.
  ASSERT_EQ(Sightmap("export " + path + " --ply " + out + "/coarse.ply --voxel 0.2").exit_code, 0);
  EXPECT_LT(ReadPly(out + "/coarse.ply").size(), cloud.size());
}

TEST(Cli, BadModelFilesExitOneWithOneLine) {
  const std::string dir = testing::MakeTempDir("cli_bad_models");
  ExpectOneLineError(Sightmap("info " + dir + "/missing.db"), 1, "does not exist");
  std::ofstream(dir + "/notes.txt") << std::string(2000, 'x');
  ExpectOneLineError(Sightmap("info " + dir + "/notes.txt --json"), 1, "not a SQLite database");
  ExpectOneLineError(Sightmap("export " + dir + "/notes.txt --ply " + dir + "/x.ply"), 1,
                     "not a SQLite database");
  const std::string model = MakeSmallModel("cli_bad_models_ok");
  ExpectOneLineError(Sightmap("export " + model + " --ply " + dir + "/no/such/dir/x.ply"), 1,
                     "cannot write");
  ExpectOneLineError(Sightmap("export " + model), 2, "nothing to export");
  ExpectOneLineError(Sightmap("info"), 2, "MODEL");
}

// sim generate: a TUM folder that probes back with ground truth, photos with per-appliance types,
// the same bytes for the same arguments.
TEST(Cli, SimGenerateWritesATumFolderThatProbesBackIdentically) {
  const std::string dir = testing::MakeTempDir("cli_sim");
  const std::string args =
      "sim generate --scene office --trajectory robot --session 2 --seed 7 --frames 3 --fps 1 "
      "--queries 2 --query-size 320x240 --out ";
  const CommandResult first = Sightmap(args + dir + "/a");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  ASSERT_EQ(Sightmap(args + dir + "/b").exit_code, 0);
  const CommandResult probe = Sightmap("probe tum:" + dir + "/a --json");
  ASSERT_EQ(probe.exit_code, 0) << probe.err;
  const nlohmann::json info = nlohmann::json::parse(probe.out);
  EXPECT_EQ(info["rgbd_frames"], 3);
  EXPECT_EQ(info["has_ground_truth"], true);
  EXPECT_EQ(info["frame_width"], 640);
  EXPECT_EQ(info["fx"], 525.0);
  EXPECT_NEAR(info["duration_s"].get<double>(), 2.0, 1e-6);
  for (const char* file : {"rgb/1.000000.png", "depth/2.000000.png", "groundtruth.txt",
                           "queries/queries.json", "queries/0001.jpg", "overview.png"}) {
    const std::string a = Slurp(dir + "/a/" + file);
    EXPECT_FALSE(a.empty()) << file;
    EXPECT_TRUE(a == Slurp(dir + "/b/" + file)) << file << " differs between identical runs";
  }
  const nlohmann::json queries = nlohmann::json::parse(Slurp(dir + "/a/queries/queries.json"));
  const nlohmann::json appliances = nlohmann::json::parse(Slurp(dir + "/a/appliances.json"));
  ASSERT_EQ(queries["queries"].size(), 2u);
  EXPECT_EQ(queries["queries"][0]["intrinsics"]["width"], 320);
  EXPECT_EQ(queries["queries"][0]["types"].size(), appliances["appliances"].size());
  EXPECT_GE(appliances["appliances"].size(), 20u);
  ExpectOneLineError(Sightmap("sim generate --frames 2"), 2, "--out");
  ExpectOneLineError(Sightmap("sim generate --scene " + dir + "/none.json --out " + dir + "/c"), 1,
                     "cannot read scene file");
}

}  // namespace
}  // namespace sightmap
