// End-to-end tests of the `sightmap` binary: exit codes, one-line errors, and the --json keys that
// scripts depend on, checked against the real recordings.
#include <sqlite3.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "store/label_files.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/synthetic_model.h"
#include "store/trajectory.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

using testing::CommandResult;
using testing::CountLines;
using testing::ExpectOneLineError;
using testing::Sightmap;
using testing::Slurp;

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
  store::Model model = store::Model::Open(path);
  store::SyntheticKeyframeOptions options;
  options.width = 160;
  options.height = 120;
  options.num_features = 20;
  std::vector<KeyframeId> ids;
  for (int session_index = 0; session_index < 2; ++session_index) {
    const SessionId session = model.BeginSession({});
    for (int i = 0; i < 2; ++i) {
      store::KeyframeRecord keyframe =
          store::MakeSyntheticKeyframe(session, session_index * 2 + i, options);
      if (i > 0) {
        store::LinkRecord odometry;
        odometry.from = ids.back();
        keyframe.links.push_back(odometry);
      }
      ids.push_back(model.AddKeyframe(keyframe));
    }
    model.EndSession(session, store::SessionEnd::kFinished, 1);
  }
  store::LinkRecord loop;
  loop.from = ids[1];
  loop.to = ids[0];
  loop.type = LinkType::kLoopClosure;
  model.AddLink(loop);
  for (const char* name_of_label : {"lamp", "projector"}) {
    store::LabelRecord label;
    label.name = name_of_label;
    store::LabelPoint point;
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
  EXPECT_EQ(info.at("synthetic_views"), 0);
  EXPECT_EQ(info.at("synthetic_view_bytes"), 0);
  EXPECT_EQ(info.at("photo_feature_keyframes"), 0);
  EXPECT_EQ(info.at("photo_feature_bytes"), 0);
  EXPECT_EQ(info.at("schema_version"), store::Model::LatestSchemaVersion());
  EXPECT_GT(info.at("size_bytes").get<int64_t>(), 10000);
  EXPECT_EQ(info.at("links").at("odometry"), 2);
  EXPECT_NEAR(info.at("bounding_box").at("max")[0].get<double>(), 1.0, 1e-9);
  const CommandResult text = Sightmap("info " + path);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("keyframes      4 in 2 segment(s)"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("lamp, projector"), std::string::npos) << text.out;
}

// The small model's four cameras stand at x = 0-0.3 m on the floor plane (up is their -y), 2 m
// before the wall the two labels hang on at (1, 0.5, 2): all four see both labels, from one
// direction, 2.18-2.29 m away.
// A model of the previous schema (as the last sightmap wrote it: no photo_features table): read
// commands refuse it naming the command that upgrades it, which does, keeping its keyframes.
TEST(Cli, InfoUpgradesAModelOfAnOlderSchema) {
  const std::string path = MakeSmallModel("cli_upgrade");
  ASSERT_EQ(Sightmap("info " + path).exit_code, 0);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(db, "DROP TABLE photo_features; DELETE FROM sightmap_schema WHERE version = 6",
                   nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(db);
  const CommandResult refused = Sightmap("info " + path + " --json");
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("older schema version 5"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("sightmap info --upgrade"), std::string::npos) << refused.err;
  EXPECT_EQ(CountLines(refused.err), 1) << refused.err;
  const CommandResult upgraded = Sightmap("info --upgrade " + path + " --json");
  ASSERT_EQ(upgraded.exit_code, 0) << upgraded.err;
  const nlohmann::json info = nlohmann::json::parse(upgraded.out);
  EXPECT_EQ(info.at("schema_version"), store::Model::LatestSchemaVersion());
  EXPECT_EQ(info.at("keyframes"), 4);
  // Keyframes of a model mapped before photo features get them (an empty row where none are
  // found), so the locator need not extract them at every start; a second upgrade has nothing
  // to do.
  EXPECT_EQ(info.at("photo_feature_keyframes"), 4);
  EXPECT_NE(upgraded.err.find("upgrade: photo features: 4/4 keyframes"), std::string::npos)
      << upgraded.err;
  const CommandResult again = Sightmap("info --upgrade " + path + " --json");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.err.find("photo features"), std::string::npos) << again.err;
  EXPECT_EQ(Sightmap("info " + path + " --json").exit_code, 0);
  EXPECT_EQ(Sightmap("info --upgrade " + path + "-missing.db").exit_code, 1);
}

TEST(Cli, CoverageSaysFromWhereEachLabelWasSeen) {
  const std::string path = MakeSmallModel("cli_coverage");
  const std::string png = testing::MakeTempDir("cli_coverage_out") + "/plan.png";
  const CommandResult run = Sightmap("coverage " + path + " --json --png " + png);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json coverage = nlohmann::json::parse(run.out);
  EXPECT_NEAR(coverage.at("up")[1].get<double>(), -1.0, 1e-9);
  ASSERT_EQ(coverage.at("labels").size(), 2u);
  for (const nlohmann::json& label : coverage.at("labels")) {
    EXPECT_EQ(label.at("keyframes"), 4);
    EXPECT_EQ(label.at("seen_sectors"), 1);
    ASSERT_EQ(label.at("sectors").size(), 12u);
    // From the label to the cameras: floor x -0.7 to -1, floor y (= world z) -2: 250-261 deg.
    const nlohmann::json& sector = label.at("sectors")[8];
    EXPECT_EQ(sector.at("from_deg"), 240.0);
    EXPECT_EQ(sector.at("keyframes"), 4);
    EXPECT_NEAR(sector.at("nearest_m").get<double>(), std::sqrt(0.7 * 0.7 + 0.25 + 4.0), 1e-6);
    EXPECT_NEAR(sector.at("farthest_m").get<double>(), std::sqrt(1.0 + 0.25 + 4.0), 1e-6);
    EXPECT_DOUBLE_EQ(label.at("share").get<double>(), 1.0 / label.at("open_sectors").get<double>());
  }
  EXPECT_EQ(coverage.at("seen_sectors"), 2);
  const cv::Mat plan = cv::imread(png);
  EXPECT_EQ(std::max(plan.cols, plan.rows), 1200);
  EXPECT_NE(run.err.find("coverage: 4/4 keyframes"), std::string::npos) << run.err;

  const CommandResult text = Sightmap("coverage " + path);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("coverage       2 of "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("lamp"), std::string::npos) << text.out;

  // info says the same share.
  const CommandResult info = Sightmap("info " + path + " --json");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(info.out).at("coverage_share").get<double>(),
                   coverage.at("share").get<double>());

  ExpectOneLineError(Sightmap("coverage " + path + " --min-distance 3 --max-distance 2"), 2,
                     "--max-distance must be greater than --min-distance");
  ExpectOneLineError(Sightmap("coverage " + path + " --png /proc/no/plan.png"), 1,
                     "cannot write --png");
  ExpectOneLineError(Sightmap("coverage " + path + " --sectors 2"), 2, "--sectors");
  ExpectOneLineError(Sightmap("coverage"), 2, "MODEL");
}

// The small model's keyframes are flat synthetic images: `synthesize` runs its coverage, plans
// standpoints around both labels, refuses or stores each view, and says so; its errors are one
// line.
TEST(Cli, SynthesizeReportsItsViewsAndRefusesAModelWithoutLabels) {
  const std::string path = MakeSmallModel("cli_synthesize");
  const CommandResult run = Sightmap("synthesize " + path + " --all-sectors --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json report = nlohmann::json::parse(run.out);
  for (const char* key : {"labels", "standpoints", "grid_standpoints", "written", "refused",
                          "deleted", "bytes", "seconds"}) {
    EXPECT_TRUE(report.contains(key)) << key;
  }
  EXPECT_EQ(report.at("grid_standpoints"), 0);  // no grid unless asked
  EXPECT_EQ(report.at("labels"), 2);
  EXPECT_EQ(report.at("written").get<int>() + report.at("refused").get<int>(),
            report.at("standpoints").get<int>());
  const CommandResult info = Sightmap("info " + path + " --json");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_EQ(nlohmann::json::parse(info.out).at("synthetic_views"), report.at("written"));

  const CommandResult text = Sightmap("synthesize " + path);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("standpoints    "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("refused        "), std::string::npos) << text.out;
  const CommandResult clear = Sightmap("synthesize " + path + " --clear --json");
  ASSERT_EQ(clear.exit_code, 0) << clear.err;
  EXPECT_TRUE(nlohmann::json::parse(clear.out).contains("deleted"));
  const CommandResult after = Sightmap("info " + path + " --json");
  EXPECT_EQ(nlohmann::json::parse(after.out).at("synthetic_views"), 0);

  ExpectOneLineError(Sightmap("synthesize " + path + " --grid -1"), 2, "--grid");
  ExpectOneLineError(Sightmap("synthesize " + path + " --grid 0.01"), 2, "at least 0.1 m");
  ExpectOneLineError(Sightmap("synthesize"), 2, "MODEL");
  ExpectOneLineError(Sightmap("synthesize /no/such/model.db"), 1, "/no/such/model.db");
  const std::string unlabelled = testing::MakeTempDir("cli_synthesize_bare") + "/model.db";
  {
    store::Model model = store::Model::Open(unlabelled);
    const SessionId session = model.BeginSession({});
    store::SyntheticKeyframeOptions small;
    small.width = 64;
    small.height = 48;
    model.AddKeyframe(store::MakeSyntheticKeyframe(session, 0, small));
  }
  ExpectOneLineError(Sightmap("synthesize " + unlabelled), 1, "has no labels");
}

TEST(Cli, ExportWritesPlyTrajectoryAndLabels) {
  const std::string path = MakeSmallModel("cli_export");
  const std::string out = testing::MakeTempDir("cli_export_out");
  const CommandResult run =
      Sightmap("export " + path + " --ply " + out + "/cloud.ply --voxel 0.05" + " --trajectory " +
               out + "/poses.txt --labels " + out + "/labels");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(run.err.empty()) << run.err;
  const std::vector<store::ColoredPoint> cloud = store::ReadPly(out + "/cloud.ply");
  EXPECT_GT(cloud.size(), 100u);
  EXPECT_NE(run.out.find(std::to_string(cloud.size()) + " points from 4 keyframes"),
            std::string::npos)
      << run.out;
  const std::vector<StampedPose> poses = ReadTumTrajectory(out + "/poses.txt");
  ASSERT_EQ(poses.size(), 4u);
  EXPECT_EQ(poses[3].timestamp_ns, 3000000000);
  EXPECT_NEAR(poses[3].world_from_cam.translation().x(), 0.3, 1e-9);
  EXPECT_EQ(store::ReadPointList(out + "/labels/projector.txt").size(), 1u);
  EXPECT_TRUE(std::ifstream(out + "/labels/lamp.txt").good());
  // A coarser voxel gives fewer points.
  ASSERT_EQ(Sightmap("export " + path + " --ply " + out + "/coarse.ply --voxel 0.2").exit_code, 0);
  EXPECT_LT(store::ReadPly(out + "/coarse.ply").size(), cloud.size());
}

TEST(Cli, BadModelFilesExitOneWithOneLine) {
  const std::string dir = testing::MakeTempDir("cli_bad_models");
  ExpectOneLineError(Sightmap("info " + dir + "/missing.db"), 1, "does not exist");
  std::ofstream(dir + "/notes.txt") << std::string(2000, 'x');
  ExpectOneLineError(Sightmap("info " + dir + "/notes.txt --json"), 1, "not a SQLite database");
  ExpectOneLineError(Sightmap("export " + dir + "/notes.txt --ply " + dir + "/x.ply"), 1,
                     "not a SQLite database");
  const std::string model = MakeSmallModel("cli_bad_models_ok");
  ExpectOneLineError(Sightmap("export " + model + " --ply /proc/no/such/dir/x.ply"), 1,
                     "cannot write --ply");
  ExpectOneLineError(Sightmap("export " + model), 2, "nothing to export");
  ExpectOneLineError(Sightmap("info"), 2, "MODEL");
}

// Numbers, sizes and outputs are judged before any work, each with the option's own name and
// a range a person can read.
TEST(Cli, BadNumbersSizesAndOutputsAreRefusedBeforeTheWork) {
  const std::string model = MakeSmallModel("cli_bad_inputs");
  const std::string dir = testing::MakeTempDir("cli_bad_inputs_out");
  const std::string map = "map --source 'sim:office?frames=3&fps=1' --headless --model " + dir;
  ExpectOneLineError(Sightmap(map + "/a.db --rate nan"), 2, "--rate: 'nan' is not a number");
  ExpectOneLineError(Sightmap(map + "/a.db --rate -1"), 2, "must be from 0 to 1000 Hz");
  ExpectOneLineError(Sightmap(map + "/a.db --rate 1e300"), 2, "must be from 0 to 1000 Hz");
  ExpectOneLineError(Sightmap(map + "/a.db --start-frame -3"), 2, "--start-frame");
  ExpectOneLineError(Sightmap(map + "/a.db --track-every 0"), 2, "must be from 1 to 1000");
  ExpectOneLineError(Sightmap("export " + model + " --ply " + dir + "/x.ply --voxel nan"), 2,
                     "--voxel: 'nan' is not a number from 0 to 10 m");
  ExpectOneLineError(Sightmap("serve --model " + model + " --port 99999"), 2,
                     "must be from 0 to 65535");
  ExpectOneLineError(Sightmap("sim generate --out " + dir + "/g --query-size 100000x100000"), 2,
                     "from 64x64 to 8000x8000");
  EXPECT_FALSE(std::filesystem::exists(dir + "/g"));
  // No message prints DBL_MAX's 309 digits.
  EXPECT_LT(Sightmap(map + "/a.db --max-keyframes -1").err.size(), 200u);

  // Outputs that cannot be written fail before mapping starts, and no model is made.
  ExpectOneLineError(Sightmap(map + "/b.db --ply /proc/x.ply"), 1,
                     "cannot write --ply /proc/x.ply");
  ExpectOneLineError(Sightmap(map + "/b.db --trajectory-out " + dir), 2, "is a folder");
  ExpectOneLineError(Sightmap(map + "/b.db --progress-png /proc/x.png"), 1,
                     "cannot write --progress-png");
  EXPECT_FALSE(std::filesystem::exists(dir + "/b.db"));
  ExpectOneLineError(Sightmap("export " + model + " --ply " + dir), 2, "is a folder");
  ExpectOneLineError(Sightmap(map + "/b.db --calib " + model), 2,
                     "does not apply to the simulator");
}

// The simulator's options in a sim: source and sim generate's --seed: each refused with its own
// name and range (frames=-1 mapped the default 9,000 frames, frames=0 blamed a --start-frame never
// given, frames=1.5 said "not a number", and a negative seed wrapped round), nothing mapped.
TEST(Cli, SimOptionsOutOfRangeAreRefusedByName) {
  const std::string dir = testing::MakeTempDir("cli_sim_options");
  const std::string map = "map --headless --model " + dir + "/m.db --source ";
  const std::string frames = "must be a whole number from 1 to 10000000";
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=-1'"), 2, "frames=-1 " + frames);
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=0'"), 2, "frames=0 " + frames);
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=1.5'"), 2, "frames=1.5 " + frames);
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=3&seed=-3'"), 2,
                     "seed=-3 must be a whole number from 0 to 18446744073709551615");
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=3&session=0'"), 2,
                     "session=0 must be a whole number from 1 to 1000");
  ExpectOneLineError(Sightmap(map + "'sim:office?frames=3&fps=0'"), 2,
                     "fps=0 must be a number above 0 and at most 120 Hz");
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.db"));
  ExpectOneLineError(Sightmap("sim generate --seed -1 --out " + dir + "/g"), 2,
                     "must be a whole number from 0 to 18446744073709551615");
  ExpectOneLineError(Sightmap("sim generate --seed 1.5 --out " + dir + "/g"), 2, "--seed");
  EXPECT_FALSE(std::filesystem::exists(dir + "/g"));
}

// info and export take the model as MODEL or --model, like every other command.
TEST(Cli, ReadCommandsTakeTheModelEitherWay) {
  const std::string model = MakeSmallModel("cli_model_flag");
  const CommandResult positional = Sightmap("info " + model + " --json");
  const CommandResult named = Sightmap("info --model " + model + " --json");
  ASSERT_EQ(named.exit_code, 0) << named.err;
  EXPECT_EQ(positional.out, named.out);
  const std::string out = testing::MakeTempDir("cli_model_flag_out");
  const CommandResult exported =
      Sightmap("export --model " + model + " --trajectory " + out + "/t.txt");
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_EQ(ReadTumTrajectory(out + "/t.txt").size(), 4u);
  ExpectOneLineError(Sightmap("info " + model + " --model " + model), 2, "excludes");
  ExpectOneLineError(Sightmap("export --trajectory " + out + "/u.txt"), 2, "give the model");
}

// locate and serve read --config like map: their own options as JSON, flags over the file, and
// --print-config shows the result without a model.
TEST(Cli, LocateAndServeReadTheirConfigAndPrintIt) {
  const std::string dir = testing::MakeTempDir("cli_config");
  std::ofstream(dir + "/locate.json")
      << R"({"min_inliers": 31, "features": {"max_features": 900}})";
  const CommandResult locate = Sightmap("locate --config " + dir + "/locate.json --print-config");
  ASSERT_EQ(locate.exit_code, 0) << locate.err;
  const nlohmann::json locator = nlohmann::json::parse(locate.out);
  EXPECT_EQ(locator.at("min_inliers"), 31);
  EXPECT_EQ(locator.at("features").at("max_features"), 900);
  EXPECT_EQ(locator.at("features").at("type"), "orb");

  std::ofstream(dir + "/serve.json")
      << R"({"port": 0, "locator": {"max_places": 2}, "labels": {"jpeg_quality": 70}})";
  const CommandResult serve =
      Sightmap("serve --port 9000 --config " + dir + "/serve.json --print-config");
  ASSERT_EQ(serve.exit_code, 0) << serve.err;
  const nlohmann::json server = nlohmann::json::parse(serve.out);
  EXPECT_EQ(server.at("port"), 9000);
  EXPECT_EQ(server.at("locator").at("max_places"), 2);
  EXPECT_EQ(server.at("labels").at("jpeg_quality"), 70);
  EXPECT_EQ(server.at("read_timeout_s"), 5);

  ExpectOneLineError(Sightmap("locate --config " + dir + "/serve.json"), 2,
                     "serve.json: labels: unknown option");
  ExpectOneLineError(Sightmap("serve --config " + dir + "/locate.json"), 2,
                     "locate.json: features: unknown option");
  ExpectOneLineError(Sightmap("locate --config " + dir + "/locate.json"), 2, "--model is required");
  ExpectOneLineError(Sightmap("serve --config " + dir + "/serve.json"), 2, "--model is required");
}

// A photo too small to hold a feature, or a JPEG cut short and closed with an end marker (libjpeg
// warns and fills the rest with grey), is a bad photo: exit 2 with one line, nothing from libjpeg
// on stderr. The photo is read before the model, so no model is needed to see it refused.
TEST(Cli, LocateRefusesTinyAndCorruptPhotos) {
  const std::string dir = testing::MakeTempDir("cli_bad_photos");
  ASSERT_TRUE(cv::imwrite(dir + "/1x1.png", cv::Mat(1, 1, CV_8UC3, cv::Scalar(1, 2, 3))));
  ASSERT_TRUE(cv::imwrite(dir + "/1x1000.jpg", cv::Mat(1000, 1, CV_8UC3, cv::Scalar(1, 2, 3))));
  ASSERT_TRUE(cv::imwrite(dir + "/1000x1.png", cv::Mat(1, 1000, CV_8UC3, cv::Scalar(1, 2, 3))));
  for (const char* name : {"1x1.png", "1x1000.jpg", "1000x1.png"}) {
    ExpectOneLineError(Sightmap("locate --model " + dir + "/none.db " + dir + "/" + name), 2,
                       "photo too small");
  }
  cv::Mat noise(480, 640, CV_8UC3);
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", noise, jpeg));
  jpeg.resize(jpeg.size() * 6 / 10);
  jpeg.push_back(0xFF);
  jpeg.push_back(0xD9);
  std::ofstream(dir + "/cut.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(jpeg.data()), static_cast<std::streamsize>(jpeg.size()));
  ExpectOneLineError(Sightmap("locate --model " + dir + "/none.db " + dir + "/cut.jpg"), 2,
                     "premature end of data segment");
}

// A folder where a file belongs gets one answer from every reader of a user-given path (it was
// "unexpected failure ... basic_filebuf::underflow", "not valid JSON", "has no poses" or "holds
// no point").
TEST(Cli, AFolderGivenForAFileIsNamedAsSuch) {
  const std::string model = MakeSmallModel("cli_folder_for_file");
  const std::string dir = testing::MakeTempDir("cli_folder_for_file_dir");
  const std::string est = dir + "/est.txt";
  std::ofstream(est) << "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n";
  const std::string fragment = dir + " is a folder: give a file";
  ExpectOneLineError(Sightmap("locate --model " + model + " " + dir), 2, fragment);
  const std::string photo = dir + "/photo.png";
  ASSERT_TRUE(cv::imwrite(photo, cv::Mat(480, 640, CV_8UC3, cv::Scalar(1, 2, 3))));
  ExpectOneLineError(Sightmap("locate --model " + model + " " + photo + " --calib " + dir), 2,
                     fragment);
  ExpectOneLineError(Sightmap("label import --model " + model + " --from-scene " + dir), 2,
                     fragment);
  ExpectOneLineError(Sightmap("label import --model " + model + " " + dir), 2, fragment);
  ExpectOneLineError(Sightmap("sim generate --scene " + dir + " --out " + dir + "/g"), 2, fragment);
  ExpectOneLineError(Sightmap("eval trajectory --gt " + dir + " --est " + est), 2, fragment);
  ExpectOneLineError(Sightmap("eval trajectory --gt " + est + " --est " + dir), 2, fragment);
  ExpectOneLineError(Sightmap("locate --config " + dir + " --print-config"), 2, fragment);
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

// --- sightmap eval trajectory ---------------------------------------------------------------

// Writes a TUM trajectory by hand: epoch timestamps with microsecond digits, like TUM RGB-D's.
void WriteTumByHand(const std::string& path, const std::vector<StampedPose>& poses) {
  std::ofstream out(path);
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& pose : poses) {
    const Eigen::Vector3d t = pose.world_from_cam.translation();
    const Eigen::Quaterniond q(pose.world_from_cam.rotation());
    char line[256];
    std::snprintf(line, sizeof(line), "%lld.%06lld %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                  static_cast<long long>(pose.timestamp_ns / 1'000'000'000),
                  static_cast<long long>(pose.timestamp_ns % 1'000'000'000 / 1000), t.x(), t.y(),
                  t.z(), q.x(), q.y(), q.z(), q.w());
    out << line;
  }
}

// 20 poses 0.5 s apart on a circle of radius 2 m at z = 0, each camera looking along the path.
std::vector<StampedPose> CircleGroundTruth() {
  std::vector<StampedPose> poses;
  for (int i = 0; i < 20; ++i) {
    const double angle = 2.0 * M_PI * i / 20.0;
    StampedPose pose;
    pose.timestamp_ns = 1'305'031'102'000'000'000 + int64_t{i} * 500'000'000;
    pose.world_from_cam.translation() =
        Eigen::Vector3d(2.0 * std::cos(angle), 2.0 * std::sin(angle), 0.0);
    pose.world_from_cam.linear() =
        Eigen::AngleAxisd(angle + M_PI, Eigen::Vector3d::UnitZ()).matrix();
    poses.push_back(pose);
  }
  return poses;
}

Eigen::Isometry3d SomeRigidMotion() {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 3).normalized()).matrix();
  motion.translation() = Eigen::Vector3d(5.0, -3.0, 1.2);
  return motion;
}

TEST(Cli, EvalTrajectoryOfARigidlyMovedCopyIsZero) {
  const std::string dir = testing::MakeTempDir("eval");
  const std::vector<StampedPose> gt = CircleGroundTruth();
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) {
    pose.world_from_cam = SomeRigidMotion() * pose.world_from_cam;
    pose.timestamp_ns += 3'000'000;  // 3 ms later: still matched
  }
  WriteTumByHand(dir + "/gt.txt", gt);
  WriteTumByHand(dir + "/est.txt", est);
  const CommandResult run =
      Sightmap("eval trajectory --gt " + dir + "/gt.txt --est " + dir + "/est.txt --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json eval = nlohmann::json::parse(run.out);
  EXPECT_EQ(eval.at("matched_poses"), 20);
  EXPECT_EQ(eval.at("gt_poses"), 20);
  EXPECT_EQ(eval.at("est_poses"), 20);
  EXPECT_LT(eval.at("ate_rmse_m").get<double>(), 1e-6);
  EXPECT_LT(eval.at("ate_max_m").get<double>(), 1e-6);
  EXPECT_LT(eval.at("rpe_trans_per_m").get<double>(), 1e-6);
  EXPECT_LT(eval.at("rpe_rot_deg_per_m").get<double>(), 1e-4);
  EXPECT_NEAR(eval.at("sim3_scale").get<double>(), 1.0, 1e-6);
  EXPECT_LT(eval.at("sim3_ate_rmse_m").get<double>(), 1e-6);
  EXPECT_GT(eval.at("rpe_pairs_distance").get<int>(), 0);
  for (const char* key :
       {"ate_mean_m", "ate_median_m", "rpe_trans_per_s", "rpe_rot_deg_per_s", "rpe_pairs_time",
        "max_time_diff_s", "rpe_distance_m", "rpe_interval_s", "gt_from_est", "plot"}) {
    EXPECT_TRUE(eval.contains(key)) << key;
  }
  // The alignment found is the inverse of the motion applied.
  const nlohmann::json& t = eval.at("gt_from_est").at("translation");
  const Eigen::Vector3d expected = SomeRigidMotion().inverse().translation();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(t.at(i).get<double>(), expected(i), 1e-6);
}

TEST(Cli, EvalTrajectoryWithTwoOppositePosesRaisedGivesKnownAte) {
  // The circle's poses 0 and 10 (diametrically opposite) are raised by d = 0.5 m. The offsets do
  // not correlate with x or y (the two poses cancel), so the best alignment has no rotation and
  // only lowers everything by the mean offset 2d/20 = 0.05 m: those two poses keep 0.45 m of error,
  // the other 18 get 0.05 m. RMSE = sqrt((2 * 0.45^2 + 18 * 0.05^2) / 20) = 0.15 m, mean (0.9 +
  // 0.9) / 20 = 0.09 m, median 0.05 m, max 0.45 m. The estimate is also moved rigidly.
  const std::string dir = testing::MakeTempDir("eval");
  const std::vector<StampedPose> gt = CircleGroundTruth();
  std::vector<StampedPose> est = gt;
  est[0].world_from_cam.translation().z() += 0.5;
  est[10].world_from_cam.translation().z() += 0.5;
  for (StampedPose& pose : est) pose.world_from_cam = SomeRigidMotion() * pose.world_from_cam;
  WriteTumByHand(dir + "/gt.txt", gt);
  WriteTumByHand(dir + "/est.txt", est);
  const std::string files = " --gt " + dir + "/gt.txt --est " + dir + "/est.txt";

  const CommandResult run =
      Sightmap("eval trajectory" + files + " --json --plot " + dir + "/plot.png");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json eval = nlohmann::json::parse(run.out);
  EXPECT_EQ(eval.at("matched_poses"), 20);
  EXPECT_NEAR(eval.at("ate_rmse_m").get<double>(), 0.15, 1e-6);
  EXPECT_NEAR(eval.at("ate_mean_m").get<double>(), 0.09, 1e-6);
  EXPECT_NEAR(eval.at("ate_median_m").get<double>(), 0.05, 1e-6);
  EXPECT_NEAR(eval.at("ate_max_m").get<double>(), 0.45, 1e-6);
  EXPECT_GT(eval.at("rpe_trans_per_m").get<double>(), 0.0);
  EXPECT_EQ(eval.at("plot"), dir + "/plot.png");
  // Where the error is: the worst 2% of 20 poses is one raised pose, 0.45^2 of the summed 0.45
  // m^2; the other 19 hold (0.45^2 + 18 x 0.05^2) / 19. The 10 s walk is one default stretch.
  EXPECT_EQ(eval.at("worst_poses"), 1);
  EXPECT_NEAR(eval.at("worst_poses_share").get<double>(), 0.45, 1e-6);
  EXPECT_NEAR(eval.at("rmse_without_worst_poses_m").get<double>(), std::sqrt(0.2475 / 19), 1e-6);
  ASSERT_EQ(eval.at("worst_stretches").size(), 1u);
  EXPECT_EQ(eval.at("worst_stretches")[0].at("poses"), 20);
  EXPECT_NEAR(eval.at("worst_stretches")[0].at("mean_m").get<double>(), 0.09, 1e-6);

  // The plot decodes at the default size, and no temporary file is left beside it.
  const cv::Mat plot = cv::imread(dir + "/plot.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(plot.empty());
  EXPECT_EQ(plot.cols, 1000);
  EXPECT_EQ(plot.rows, 800);
  int files_in_dir = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    ++files_in_dir;
    (void)entry;
  }
  EXPECT_EQ(files_in_dir, 3);  // gt.txt, est.txt, plot.png

  // Text output: the table with units; --plot-size and options change what they say.
  const CommandResult text =
      Sightmap("eval trajectory" + files + " --plot " + dir +
               "/small.png --plot-size 400x300 --rpe-distance 2 --stretch 1");
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("ATE rmse"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("0.1500"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("0.4500"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("m/m"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("deg/m"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("deg/s"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("over 2.00 m"), std::string::npos) << text.out;
  // One-second stretches: t = 0-1 s and 5-6 s each hold a raised pose and a level one.
  EXPECT_NE(text.out.find("worst stretch             0.2500  m       mean over t = 0.0-1.0 s "
                          "(2 poses, max 0.4500 m)"),
            std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("the worst 1 pose;"), std::string::npos) << text.out;
  const cv::Mat small = cv::imread(dir + "/small.png", cv::IMREAD_COLOR);
  EXPECT_EQ(small.cols, 400);
  EXPECT_EQ(small.rows, 300);
}

TEST(Cli, EvalTrajectoryErrorsExitWithOneLine) {
  const std::string dir = testing::MakeTempDir("eval");
  const std::vector<StampedPose> gt = CircleGroundTruth();
  WriteTumByHand(dir + "/gt.txt", gt);
  const std::string gt_arg = " --gt " + dir + "/gt.txt";

  ExpectOneLineError(Sightmap("eval"), 2, "");
  ExpectOneLineError(Sightmap("eval trajectory --est " + dir + "/gt.txt"), 2, "--gt");
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/gt.txt --plot " +
                              dir + "/p.png --plot-size big"),
                     2, "--plot-size");
  ExpectOneLineError(
      Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/gt.txt --rpe-distance 0"), 2,
      "--rpe-distance");
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/missing.txt"), 1,
                     "missing.txt");

  // A malformed third line is named by file and line.
  {
    std::ofstream bad(dir + "/bad.txt");
    bad << "# comment\n1305031102.0 0 0 0 0 0 0 1\n1305031102.5 0 0 zero 0 0 0 1\n";
  }
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/bad.txt"), 1,
                     "bad.txt:3");
  {
    std::ofstream empty(dir + "/empty.txt");
    empty << "# nothing here\n";
  }
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/empty.txt"), 1,
                     "no poses");

  // Another clock: nothing matches within 20 ms.
  std::vector<StampedPose> late = gt;
  for (StampedPose& pose : late) pose.timestamp_ns += 1'000'000'000'000;
  WriteTumByHand(dir + "/late.txt", late);
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/late.txt"), 1,
                     "only 0 of 20");
  // 30 ms late does not match by default, and does with --max-time-diff 0.05.
  for (StampedPose& pose : late)
    pose.timestamp_ns = pose.timestamp_ns - 1'000'000'000'000 + 30'000'000;
  WriteTumByHand(dir + "/late.txt", late);
  ExpectOneLineError(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/late.txt"), 1,
                     "only 0 of 20");
  EXPECT_EQ(
      Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/late.txt --max-time-diff 0.05")
          .exit_code,
      0);

  // An unwritable plot path fails before evaluating; a missing folder is made, as for every
  // output.
  ExpectOneLineError(
      Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/gt.txt --plot /proc/no/plot.png"),
      1, "cannot write --plot /proc/no/plot.png");
  ASSERT_EQ(Sightmap("eval trajectory" + gt_arg + " --est " + dir + "/gt.txt --plot " + dir +
                     "/new/folder/plot.png")
                .exit_code,
            0);
  EXPECT_FALSE(cv::imread(dir + "/new/folder/plot.png").empty());
}

}  // namespace
}  // namespace sightmap
