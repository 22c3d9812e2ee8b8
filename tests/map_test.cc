// End-to-end tests of `sightmap map` (issue 8): the real recordings, the simulator with progress
// images, Ctrl-C, a SIGKILL at a random moment and the resumed session, the no-sensor error, and a
// recording played at its recorded pace through the live-sensor path.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/timing.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/trajectory.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

using namespace std::chrono_literals;

// Frame 0 of the default (seed 1) walk faces a bare wall: the map starts on frame 1
// (slam::TrackerOptions::start_max_wait_s), so a walk of n frames at 1 Hz maps n - 1 keyframes.
constexpr int kBareStartFrames = 1;

using testing::CommandResult;
using testing::CountLines;
using testing::Sightmap;
using testing::Slurp;

// A `sightmap` process started in the background, so a test can signal it.
class Background {
 public:
  explicit Background(const std::string& args) : dir_(testing::MakeTempDir("background")) {
    const std::string command = "exec " + std::string(SIGHTMAP_BINARY) + " " + args + " > " + dir_ +
                                "/out 2> " + dir_ + "/err < /dev/null";
    pid_ = fork();
    if (pid_ == 0) {
      execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Background() {
    if (pid_ > 0 && !waited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  Background(const Background&) = delete;
  Background& operator=(const Background&) = delete;

  pid_t pid() const { return pid_; }
  bool Running() {
    if (waited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      Finish(status);
      return false;
    }
    return true;
  }
  void Signal(int signal_number) { kill(pid_, signal_number); }
  std::string ErrorOutput() const { return Slurp(dir_ + "/err"); }
  CommandResult Wait() {
    if (!waited_) {
      int status = 0;
      waitpid(pid_, &status, 0);
      Finish(status);
    }
    CommandResult run;
    run.exit_code = exit_code_;
    run.out = Slurp(dir_ + "/out");
    run.err = Slurp(dir_ + "/err");
    return run;
  }

 private:
  void Finish(int status) {
    waited_ = true;
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

  std::string dir_;
  pid_t pid_ = -1;
  bool waited_ = false;
  int exit_code_ = -1;
};

// Committed keyframes of a model another process is writing (0 while it does not exist yet).
int64_t CommittedKeyframes(const std::string& path) {
  if (!std::filesystem::exists(path)) return 0;
  try {
    return store::Model::Open(path, store::ModelOptions::ReadOnly()).NumKeyframes();
  } catch (const std::exception&) {
    return 0;  // created but the schema not committed yet
  }
}

// Waits until the model holds `keyframes` committed keyframes; false if `process` ended first.
bool WaitForKeyframes(Background& process, const std::string& model, int64_t keyframes) {
  const auto deadline = std::chrono::steady_clock::now() + 240s;
  while (std::chrono::steady_clock::now() < deadline) {
    if (CommittedKeyframes(model) >= keyframes) return true;
    if (!process.Running()) return false;
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

nlohmann::json Info(const std::string& model) {
  const CommandResult info = Sightmap("info " + model + " --json");
  EXPECT_EQ(info.exit_code, 0) << info.err;
  return nlohmann::json::parse(info.out);
}

// Whether two keyframes are joined by a chain of measured links: a motion-model link (kPrior) is
// a guess across seconds nothing registered, good to tens of centimetres at 1 Hz.
bool Connected(const std::vector<store::LinkRecord>& links, KeyframeId a, KeyframeId b) {
  std::map<int64_t, int64_t> parent;
  std::function<int64_t(int64_t)> root = [&](int64_t id) {
    auto it = parent.find(id);
    if (it == parent.end() || it->second == id) return id;
    return it->second = root(it->second);
  };
  for (const store::LinkRecord& link : links) {
    if (link.type == LinkType::kPrior) continue;
    const int64_t from = root(link.from.value());
    const int64_t to = root(link.to.value());
    if (from != to) parent[from] = to;
  }
  return root(a.value()) == root(b.value());
}

// A recording replayed as fast as the mapper reads: every frame a keyframe at --rate 30.
void ExpectRecordingMapsEveryFrame(const std::string& recording, int frames) {
  const std::string dir = testing::MakeTempDir("map");
  const CommandResult run = Sightmap("map --source " + recording + " --rate 30 --model " + dir +
                                     "/m.db --ply " + dir + "/m.ply --headless --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json summary = nlohmann::json::parse(run.out);
  EXPECT_EQ(summary.at("keyframes"), frames);
  // Every frame tracked, and the recording one connected part.
  EXPECT_EQ(summary.at("tracked_frames"), frames);
  EXPECT_EQ(summary.at("segments"), 1);
  EXPECT_EQ(summary.at("largest_part_ratio"), 1.0);
  EXPECT_EQ(summary.at("dropped_frames"), 0) << "a replay waits for the mapper";
  EXPECT_EQ(summary.at("reason"), "the source ended");
  // The end's whole-map optimisation is timed, and the status line says it is running.
  EXPECT_GT(summary.at("final_optimisation_s").get<double>(), 0.0);
  EXPECT_NE(run.err.find("optimising the whole map"), std::string::npos) << run.err;
  EXPECT_EQ(Info(dir + "/m.db").at("keyframes"), frames);
  const store::Model model = store::Model::Open(dir + "/m.db", store::ModelOptions::ReadOnly());
  EXPECT_EQ(model.NumKeyframes(), frames);
  ASSERT_EQ(model.Sessions().size(), 1u);
  EXPECT_EQ(model.Sessions()[0].end_state, store::SessionEnd::kFinished);
  const std::vector<store::ColoredPoint> cloud = store::ReadPly(dir + "/m.ply");
  EXPECT_GT(cloud.size(), 1000u);
  EXPECT_EQ(static_cast<int64_t>(cloud.size()), summary.at("ply_points").get<int64_t>());
}

TEST(Map, TheKinectRecordingGivesTwelveKeyframesAndAPly) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  ExpectRecordingMapsEveryFrame(path, 12);
}

TEST(Map, TheOpenNi2RecordingGivesAKeyframePerPairedFrame) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/openni2-24f.oni");
  // 24 depth frames, the last without a colour partner: 23 RGB-D frames (see cli_test's probe).
  const CommandResult probe = Sightmap("probe " + path + " --json");
  ASSERT_EQ(probe.exit_code, 0) << probe.err;
  const int paired = nlohmann::json::parse(probe.out).at("rgbd_frames").get<int>();
  EXPECT_EQ(paired, 23);
  ExpectRecordingMapsEveryFrame(path, paired);
}

// Five real frames make a model too small for the mapper's vocabulary (it trains on 30): its
// photos must still be located, not refused as "not written by a complete map run".
TEST(Map, AFiveFrameRealModelLocatesItsPhotos) {
  SIGHTMAP_REQUIRE_SHARED_DATA(folder, "rgbd/3dmatch-lounge/seq-01");
  const std::string dir = testing::MakeTempDir("lounge-locate");
  const CommandResult run = Sightmap("map --source 3dmatch:" + folder + " --rate 30 --model " +
                                     dir + "/m.db --headless --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ASSERT_EQ(nlohmann::json::parse(run.out).at("keyframes"), 5);
  const CommandResult located = Sightmap("locate --model " + dir + "/m.db " + folder +
                                         "/frame-000001.color.png --intrinsics "
                                         "570.342205,570.342205,320,240 --json");
  ASSERT_EQ(located.exit_code, 0) << located.err;
  const nlohmann::json answer = nlohmann::json::parse(located.out);
  EXPECT_EQ(answer.at("matched"), true) << located.out;
  EXPECT_EQ(answer.at("intrinsics").at("source"), "given");
  // A --config the locator cannot meet: the same photo is refused, so the options reach it.
  std::ofstream(dir + "/strict.json") << R"({"min_inliers": 100000, "confident_inliers": 100000})";
  const CommandResult strict =
      Sightmap("locate --config " + dir + "/strict.json --model " + dir + "/m.db " + folder +
               "/frame-000001.color.png --intrinsics 570.342205,570.342205,320,240 --json");
  ASSERT_EQ(strict.exit_code, 0) << strict.err;
  EXPECT_EQ(nlohmann::json::parse(strict.out).at("matched"), false) << strict.out;
}

// The 12-frame Kinect recording at the default rate is a model of one keyframe: no vocabulary can
// be trained on it, and the locator must try that keyframe rather than refuse the model as
// having "no keyframe with ORB features".
TEST(Map, AOneKeyframeModelLocatesItsPhotos) {
  SIGHTMAP_REQUIRE_SHARED_DATA(recording, "oni/kinect-12f.oni");
  const std::string dir = testing::MakeTempDir("one-keyframe");
  const CommandResult run =
      Sightmap("map --source " + recording + " --model " + dir + "/m.db --headless --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ASSERT_EQ(nlohmann::json::parse(run.out).at("keyframes"), 1);
  ASSERT_EQ(Sightmap("probe " + recording + " --dump 12 --out " + dir + "/frames").exit_code, 0);
  // The recording's colour intrinsics, as the dump writes them (3DMatch's 3x3 matrix).
  std::ifstream matrix(dir + "/frames/camera-intrinsics.txt");
  double k[9] = {};
  for (double& entry : k) ASSERT_TRUE(matrix >> entry);
  std::ostringstream intrinsics;
  intrinsics.precision(17);
  intrinsics << k[0] << "," << k[4] << "," << k[2] << "," << k[5];
  for (const char* frame : {"frame-000000", "frame-000011"}) {
    const CommandResult located =
        Sightmap("locate --model " + dir + "/m.db " + dir + "/frames/" + frame +
                 ".color.png --intrinsics " + intrinsics.str() + " --json");
    ASSERT_EQ(located.exit_code, 0) << located.err;
    EXPECT_EQ(nlohmann::json::parse(located.out).at("matched"), true) << frame << located.out;
  }
}

TEST(Map, ASimWalkWritesProgressImageTrajectoryAndAte) {
  const std::string dir = testing::MakeTempDir("sim");
  const CommandResult run = Sightmap("map --source 'sim:office?frames=40&fps=1' --model " + dir +
                                     "/m.db --ply " + dir + "/m.ply --headless --progress-png " +
                                     dir + "/p.png --trajectory-out " + dir + "/t.txt");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("map: " + std::to_string(40 - kBareStartFrames) + " keyframes"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("started     after 1 frame too bare"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("ATE "), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("stopped: the source ended"), std::string::npos) << run.out;
  const cv::Mat png = cv::imread(dir + "/p.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 1280);
  EXPECT_EQ(png.rows, 720);
  cv::Scalar mean, stddev;
  cv::meanStdDev(png, mean, stddev);
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 10.0) << "the progress image is blank";
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.png.tmp"));
  EXPECT_EQ(ReadTumTrajectory(dir + "/t.txt").size(), static_cast<size_t>(40 - kBareStartFrames));
  EXPECT_GT(store::ReadPly(dir + "/m.ply").size(), 10000u);
}

// The summary's ATE is the one `eval trajectory` computes from the exported trajectory and the
// walk's ground truth (as `sim generate` writes it), and no worse than measured.
TEST(Map, ASimSummaryAsJsonHasAnAte) {
  const std::string dir = testing::MakeTempDir("sim-json");
  const CommandResult run =
      Sightmap("map --source 'sim:office?frames=15&fps=1' --model " + dir +
               "/m.db --headless --json --trajectory-out " + dir + "/est.txt");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json summary = nlohmann::json::parse(run.out);
  const int keyframes = 15 - kBareStartFrames;
  EXPECT_EQ(summary.at("keyframes"), keyframes);
  EXPECT_EQ(summary.at("frames_before_start"), kBareStartFrames);
  EXPECT_EQ(summary.at("source_kind"), "sim");
  ASSERT_TRUE(summary.at("ate_rmse_m").is_number());
  EXPECT_EQ(summary.at("ate_poses"), keyframes);
  ASSERT_EQ(Sightmap("sim generate --frames 15 --fps 1 --queries 0 --out " + dir + "/gt").exit_code,
            0);
  const CommandResult eval = Sightmap("eval trajectory --gt " + dir + "/gt/groundtruth.txt --est " +
                                      dir + "/est.txt --json");
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  const nlohmann::json error = nlohmann::json::parse(eval.out);
  EXPECT_EQ(error.at("matched_poses"), keyframes);
  EXPECT_NEAR(summary.at("ate_rmse_m").get<double>(), error.at("ate_rmse_m").get<double>(), 1e-6);
  EXPECT_NEAR(summary.at("ate_max_m").get<double>(), error.at("ate_max_m").get<double>(), 1e-6);
  // Measured 0.49 m: 15 keyframes at 1 Hz with only keyframes tracked is the paper's capture, far
  // from issue 17's 1 Hz target of 0.10 m; this guards against it getting worse.
  EXPECT_LT(summary.at("ate_rmse_m").get<double>(), 0.75);
  EXPECT_EQ(summary.at("segments").get<int64_t>(), Info(dir + "/m.db").at("segments"));
  EXPECT_EQ(summary.at("largest_segment_keyframes").get<int64_t>(),
            Info(dir + "/m.db").at("largest_segment_keyframes"));
}

// The same command again continues the walk after its last stored frame, says so, and once the
// walk is all in says there is nothing left; --start-frame overrides the continuation.
TEST(Map, TheSameCommandAgainContinuesTheWalkAndStartFrameOverrides) {
  const std::string dir = testing::MakeTempDir("sim-continue");
  const std::string command =
      "map --source 'sim:office?frames=12&fps=1' --model " + dir + "/m.db --headless --json";
  const CommandResult first = Sightmap(command + " --max-keyframes 5");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const CommandResult second = Sightmap(command);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  // The first run stored frames 1-5 (frame 0 could not anchor the map).
  EXPECT_NE(second.err.find("continuing sim:office?frames=12&fps=1 after its last stored frame "
                            "(t = 5.000 s)"),
            std::string::npos)
      << second.err;
  const nlohmann::json summary = nlohmann::json::parse(second.out);
  EXPECT_EQ(summary.at("keyframes"), 6);
  EXPECT_EQ(summary.at("frames_skipped"), 6);
  EXPECT_EQ(summary.at("frames_before_start"), 0);
  EXPECT_DOUBLE_EQ(summary.at("continued_after_s").get<double>(), 5.0);
  {
    // The camera is where the stored walk left it: the first new keyframe is odometry from the
    // last stored one, not a part of its own that waits for a relocalisation to hang it on.
    const store::Model model = store::Model::Open(dir + "/m.db", store::ModelOptions::ReadOnly());
    const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
    ASSERT_EQ(keyframes.size(), static_cast<size_t>(12 - kBareStartFrames));
    bool continued = false;
    for (const store::LinkRecord& link : model.Links()) {
      continued |= link.from == keyframes[4].id && link.to == keyframes[5].id &&
                   link.type == LinkType::kOdometry;
    }
    EXPECT_TRUE(continued);
  }

  // A run that maps nothing leaves the model as it was: no empty finished session either.
  const nlohmann::json before = Info(dir + "/m.db");
  const CommandResult third = Sightmap(command);
  EXPECT_EQ(third.exit_code, 1);
  EXPECT_NE(third.err.find("nothing left to map"), std::string::npos) << third.err;
  const nlohmann::json after = Info(dir + "/m.db");
  EXPECT_EQ(after.at("keyframes"), 12 - kBareStartFrames);
  EXPECT_EQ(after.at("sessions"), before.at("sessions"));
  EXPECT_EQ(after.at("session_list"), before.at("session_list"));

  const CommandResult again = Sightmap(command + " --start-frame 10");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(nlohmann::json::parse(again.out).at("keyframes"), 2);
  EXPECT_EQ(again.err.find("continuing"), std::string::npos) << again.err;
  const CommandResult past = Sightmap(command + " --start-frame 12");
  EXPECT_EQ(past.exit_code, 2);  // a usage error
  EXPECT_NE(past.err.find("past the end"), std::string::npos) << past.err;
}

TEST(Map, TracksEveryFrameAtTenHertzAndKeepsOneKeyframeASecondInOnePart) {
  const std::string dir = testing::MakeTempDir("sim-10hz");
  const CommandResult run =
      Sightmap("map --source 'sim:office?frames=120&fps=10&seed=11' --model " + dir +
               "/m.db --headless --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json summary = nlohmann::json::parse(run.out);
  EXPECT_EQ(summary.at("tracked_frames"), 120);
  // The office's walls and floor give most keyframes the building's axes (a rotation prior).
  EXPECT_GT(summary.at("axes_keyframes").get<int>(), 0);
  EXPECT_LE(summary.at("axes_keyframes").get<int>(), summary.at("keyframes").get<int>());
  // 12 s: 12 on the 1 Hz clock, and early ones where the overlap ran out (the walk starts
  // facing a bare wall at arm's length).
  EXPECT_GE(summary.at("keyframes").get<int>(), 12);
  EXPECT_LE(summary.at("keyframes").get<int>(), 40);
  EXPECT_EQ(summary.at("segments"), 1);
  EXPECT_EQ(summary.at("largest_part_ratio"), 1.0);
  EXPECT_LT(summary.at("ate_rmse_m").get<double>(), 0.10);
  EXPECT_LT(summary.at("dense_frames").get<int64_t>() + summary.at("blind_frames").get<int64_t>(),
            60)
      << "most frames of an ordinary walk register by features";
  EXPECT_GT(summary.at("track_median_ms").get<double>(), 0.0);
  const nlohmann::json info = Info(dir + "/m.db");
  EXPECT_EQ(info.at("prior_links"), summary.at("prior_links"));
  EXPECT_EQ(info.at("largest_part_ratio"), 1.0);
  // --no-tracking maps the 1 Hz keyframes only, as before.
  const CommandResult untracked =
      Sightmap("map --source 'sim:office?frames=30&fps=10&seed=11' --no-tracking --model " + dir +
               "/u.db --headless --json");
  ASSERT_EQ(untracked.exit_code, 0) << untracked.err;
  const nlohmann::json plain = nlohmann::json::parse(untracked.out);
  EXPECT_EQ(plain.at("tracked_frames"), 0);
  EXPECT_EQ(plain.at("keyframes"), 3);
}

// The model keeps every option a session ran with (info --json), and that is the config that runs
// it again: --config reads it, and a flag given beside it wins whatever the order.
TEST(Map, ASessionsOptionsAreInTheModelAndAreTheConfigThatRunsItAgain) {
  const std::string dir = testing::MakeTempDir("config");
  const CommandResult run =
      Sightmap("map --source 'sim:office?frames=6&fps=1' --model " + dir +
               "/m.db --headless --json --rate 2 --no-tracking --max-keyframes 4");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json options = Info(dir + "/m.db").at("session_list").at(0).at("options");
  EXPECT_EQ(options.at("source"), "sim:office?frames=6&fps=1");
  EXPECT_EQ(options.at("sampler").at("rate_hz"), 2.0);
  EXPECT_EQ(options.at("max_keyframes"), 4);
  EXPECT_EQ(options.at("tracking").at("track"), false);
  EXPECT_EQ(options.at("show_view"), false);
  // The tracker as it ran: with the mapper's features, at the keyframe rate.
  EXPECT_EQ(options.at("tracking").at("tracker").at("features"),
            options.at("mapper").at("features"));
  EXPECT_EQ(options.at("tracking").at("tracker").at("keyframe_rate_hz"), 2.0);
  EXPECT_GT(options.at("mapper").size(), 30u);
  std::ofstream(dir + "/session.json") << options.dump(2);

  const CommandResult printed =
      Sightmap("map --config " + dir + "/session.json --model " + dir + "/m.db --print-config");
  ASSERT_EQ(printed.exit_code, 0) << printed.err;
  EXPECT_EQ(nlohmann::json::parse(printed.out), options);
  for (const std::string& order : {"--rate 3 --config " + dir + "/session.json",
                                   "--config " + dir + "/session.json --rate 3"}) {
    const CommandResult flagged = Sightmap("map " + order + " --print-config");
    ASSERT_EQ(flagged.exit_code, 0) << flagged.err;
    EXPECT_EQ(nlohmann::json::parse(flagged.out).at("sampler").at("rate_hz"), 3.0) << order;
  }

  const CommandResult again =
      Sightmap("map --config " + dir + "/session.json --model " + dir + "/again.db --json");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(nlohmann::json::parse(again.out).at("keyframes"), 4);
  EXPECT_EQ(nlohmann::json::parse(again.out).at("tracked_frames"), 0);
  nlohmann::json rerun = Info(dir + "/again.db").at("session_list").at(0).at("options");
  EXPECT_EQ(rerun.at("model_path"), dir + "/again.db");
  rerun["model_path"] = options.at("model_path");
  EXPECT_EQ(rerun, options);
}

TEST(Map, ABadConfigIsOneLineThatNamesTheFileAndTheKey) {
  const std::string dir = testing::MakeTempDir("bad-config");
  const auto run_with = [&dir](const std::string& text) {
    std::ofstream(dir + "/c.json") << text;
    return Sightmap("map --config " + dir + "/c.json --model " + dir +
                    "/m.db --source 'sim:office?frames=3' --headless");
  };
  testing::ExpectOneLineError(run_with(R"({"mapper": {"loop_candidate": 5}})"), 2,
                              dir +
                                  "/c.json: mapper.loop_candidate: unknown option; did you "
                                  "mean loop_candidates?");
  testing::ExpectOneLineError(run_with(R"({"sampler": {"rate_hz": "fast"}})"), 2,
                              "sampler.rate_hz: must be a number");
  testing::ExpectOneLineError(run_with(R"({"track_every": 1.5})"), 2,
                              "track_every: must be a whole number");
  testing::ExpectOneLineError(run_with(R"({"sampler": {"rate_hz": -1}})"), 2, "rate_hz");
  testing::ExpectOneLineError(run_with("{\n  \"live\": true,\n"), 2,
                              "c.json is not valid JSON: parse error at line 3");
  testing::ExpectOneLineError(
      Sightmap("map --config " + dir + "/none.json --model " + dir + "/m.db"), 2,
      "--config " + dir + "/none.json: No such file or directory");
  testing::ExpectOneLineError(Sightmap("map --config " + dir + " --model " + dir + "/m.db"), 2,
                              "is a folder");
  testing::ExpectOneLineError(run_with(R"({"live": )" + std::string(1 << 20, ' ') + "true}"), 2,
                              "c.json is over 1 MiB");
  testing::ExpectOneLineError(run_with(R"({"sampler": {"rate_hz": 1e999}})"), 2, "number overflow");
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.db")) << "no model from a bad config";
  // The defaults need neither a model nor a source.
  const CommandResult defaults = Sightmap("map --print-config");
  ASSERT_EQ(defaults.exit_code, 0) << defaults.err;
  EXPECT_EQ(nlohmann::json::parse(defaults.out).at("sampler").at("rate_hz"), 1.0);
}

TEST(Map, WithoutASensorTheDefaultSourceFailsWithOneLine) {
  const CommandResult devices = Sightmap("devices --json");
  ASSERT_EQ(devices.exit_code, 0) << devices.err;
  if (!nlohmann::json::parse(devices.out).at("sensors").empty()) {
    GTEST_SKIP() << "a sensor is attached";
  }
  const std::string dir = testing::MakeTempDir("nosensor");
  const CommandResult run = Sightmap("map --model " + dir + "/m.db --headless");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_EQ(run.err, "error: no RGB-D sensor found — run 'sightmap devices'\n");
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.db")) << "no source, no model";
}

TEST(Map, UsageErrors) {
  EXPECT_EQ(Sightmap("map --source x.oni").exit_code, 2);  // no --model
  EXPECT_EQ(Sightmap("map --model m.db --preview --headless").exit_code, 2);
  const CommandResult missing = Sightmap("map --source /no/such.oni --model /tmp/x-never.db");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(CountLines(missing.err), 1) << missing.err;
}

TEST(Map, CtrlCFinishesCommitsWritesThePlyAndExitsZero) {
  const std::string dir = testing::MakeTempDir("sigint");
  const std::string model = dir + "/m.db";
  Background run("map --source 'sim:office?frames=300&fps=1' --model " + model + " --ply " + dir +
                 "/m.ply --headless");
  ASSERT_TRUE(WaitForKeyframes(run, model, 5)) << run.Wait().err;
  run.Signal(SIGINT);
  const auto signalled = std::chrono::steady_clock::now();
  const CommandResult result = run.Wait();
  const double stop_s = SecondsSince(signalled);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("stopped: interrupted"), std::string::npos) << result.out;
  EXPECT_LT(stop_s, 30.0);
  const store::Model reopened = store::Model::Open(model, store::ModelOptions::ReadOnly());
  const int64_t keyframes = reopened.NumKeyframes();
  EXPECT_GE(keyframes, 5);
  EXPECT_LT(keyframes, 300);
  EXPECT_NE(result.out.find("map: " + std::to_string(keyframes) + " keyframes"), std::string::npos)
      << result.out;
  ASSERT_EQ(reopened.Sessions().size(), 1u);
  EXPECT_EQ(reopened.Sessions()[0].end_state, store::SessionEnd::kFinished);
  EXPECT_GT(store::ReadPly(dir + "/m.ply").size(), 1000u);
  std::printf("SIGINT after >= 5 keyframes: %lld keyframes kept, stopped in %.2f s\n",
              static_cast<long long>(keyframes), stop_s);
}

TEST(Map, ASecondCtrlCExitsAtOnceAndTheModelStillOpens) {
  const std::string dir = testing::MakeTempDir("sigint2");
  const std::string model = dir + "/m.db";
  Background run("map --source 'sim:office?frames=300&fps=1' --model " + model + " --ply " + dir +
                 "/m.ply --headless");
  ASSERT_TRUE(WaitForKeyframes(run, model, 10)) << run.Wait().err;
  run.Signal(SIGINT);
  // Signals do not queue: the second must come after the first was handled (it says so).
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (run.ErrorOutput().find("Ctrl-C again") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(1ms);
  }
  run.Signal(SIGINT);
  const CommandResult result = run.Wait();
  EXPECT_EQ(result.exit_code, 128 + SIGINT) << result.err;
  EXPECT_NE(result.err.find("second signal"), std::string::npos) << result.err;
  const store::Model reopened = store::Model::Open(model, store::ModelOptions::ReadOnly());
  EXPECT_EQ(reopened.IntegrityCheck(), "ok");
  EXPECT_GE(reopened.NumKeyframes(), 10);
}

// SIGKILL at a random moment, then `map` again on the same model with the same walk from a place
// the first session mapped before the kill: a new session, the crashed one marked interrupted,
// every committed keyframe kept, and the resumed keyframes relocalised into the stored graph (no
// new segment). The kill waits for the vocabulary (trained at 30 keyframes and stored with the
// 30th): a model killed before it has no place recognition to relocalise with until the new session
// trains one.
TEST(Map, AKilledRunResumesIntoTheSameGraph) {
  const std::string dir = testing::MakeTempDir("kill");
  const std::string model = dir + "/m.db";
  const std::string walk = "'sim:office?frames=120&fps=1'";
  // A different moment every run, said in every failure; SIGHTMAP_TEST_SEED=N replays one.
  const char* given_seed = std::getenv("SIGHTMAP_TEST_SEED");
  const unsigned seed =
      given_seed ? static_cast<unsigned>(std::stoul(given_seed)) : std::random_device{}();
  std::mt19937 random(seed);
  const int extra_ms = std::uniform_int_distribution<int>(0, 2000)(random);
  SCOPED_TRACE("killed " + std::to_string(extra_ms) + " ms after keyframe 31 (SIGHTMAP_TEST_SEED=" +
               std::to_string(seed) + " replays it)");
  int64_t committed = 0;
  {
    Background run("map --source " + walk + " --model " + model + " --headless");
    ASSERT_TRUE(WaitForKeyframes(run, model, 31)) << run.Wait().err;
    std::this_thread::sleep_for(std::chrono::milliseconds(extra_ms));
    run.Signal(SIGKILL);
    EXPECT_EQ(run.Wait().exit_code, 128 + SIGKILL);
    const store::Model killed = store::Model::Open(model, store::ModelOptions::ReadOnly());
    EXPECT_EQ(killed.IntegrityCheck(), "ok");
    committed = killed.NumKeyframes();
    ASSERT_EQ(killed.Sessions().size(), 1u);
    EXPECT_EQ(killed.Sessions()[0].end_state, store::SessionEnd::kRunning)
        << "as a crash leaves it";
    EXPECT_TRUE(killed.LoadVocabulary().has_value());
  }
  const int64_t segments_before = Info(model).at("segments").get<int64_t>();
  // The resumed walk revisits frames 15-29, which the kill (after keyframe 31) always left
  // committed. Resuming just before the kill point instead fails now and then: at some points of
  // this walk the ten frames before it are views no keyframe can be registered to (a bare wall),
  // with or without a crash.
  const int64_t start = 15;
  const CommandResult resumed =
      Sightmap("map --source " + walk + " --start-frame " + std::to_string(start) +
               " --max-keyframes 15 --model " + model + " --headless --json");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  const nlohmann::json summary = nlohmann::json::parse(resumed.out);
  EXPECT_EQ(summary.at("resumed"), true);
  EXPECT_EQ(summary.at("restored_keyframes"), committed);
  EXPECT_EQ(summary.at("interrupted_sessions_marked"), 1);
  EXPECT_EQ(summary.at("keyframes"), 15);
  EXPECT_EQ(summary.at("joined_stored_map"), true) << resumed.out;

  const store::Model after = store::Model::Open(model, store::ModelOptions::ReadOnly());
  EXPECT_EQ(after.IntegrityCheck(), "ok");
  EXPECT_EQ(after.NumKeyframes(), committed + 15);
  const std::vector<store::SessionRecord> sessions = after.Sessions();
  ASSERT_EQ(sessions.size(), 2u);
  EXPECT_EQ(sessions[0].end_state, store::SessionEnd::kInterrupted);
  EXPECT_EQ(sessions[1].end_state, store::SessionEnd::kFinished);
  const nlohmann::json info = Info(model);
  EXPECT_EQ(info.at("sessions"), 2);
  EXPECT_GE(info.at("links").at("relocalisation").get<int64_t>(), 1);
  // Resumed keyframes revisiting frames start..start+14 that the graph joins to the stored
  // keyframe of the same frame (through any chain of measured links) must land where the first
  // session put that frame; at least one must (at 1 Hz odometry is lost now and then, so not
  // every revisit joins, and the total segment count may grow by ordinary losses: that is slam's
  // business). A keyframe held by a motion-model link alone need not: the resumed session's last
  // keyframe (t = 29 s) is blind and keeps the motion model's guess, while the first session
  // bridged its twin once the next keyframe registered (0.16 m apart).
  const std::vector<store::KeyframeInfo> keyframes = after.Keyframes();
  const std::vector<store::LinkRecord> links = after.Links();
  // The twin of a frame is the first session's keyframe of the same timestamp.
  std::map<TimestampNs, const store::KeyframeInfo*> first_session;
  for (int64_t k = 0; k < committed; ++k) {
    first_session[keyframes[static_cast<size_t>(k)].timestamp_ns] =
        &keyframes[static_cast<size_t>(k)];
  }
  int joined_revisits = 0;
  for (size_t k = static_cast<size_t>(committed); k < keyframes.size(); ++k) {
    const store::KeyframeInfo& again = keyframes[k];
    const auto twin = first_session.find(again.timestamp_ns);
    ASSERT_NE(twin, first_session.end()) << "a resumed keyframe of a frame the kill never reached";
    if (!Connected(links, twin->second->id, again.id)) continue;
    ++joined_revisits;
    EXPECT_LT(
        (twin->second->world_from_cam.translation() - again.world_from_cam.translation()).norm(),
        0.10)
        << "t = " << 1e-9 * static_cast<double>(again.timestamp_ns) << " s";
  }
  EXPECT_GE(joined_revisits, 1) << "the resumed keyframes must join the stored graph";
  std::printf(
      "killed %d ms after keyframe 31: %lld committed; resumed from frame %lld: 15 more; "
      "segments %lld before, %lld after; %d of 15 revisits joined\n",
      extra_ms, static_cast<long long>(committed), static_cast<long long>(start),
      static_cast<long long>(segments_before),
      static_cast<long long>(info.at("segments").get<int64_t>()), joined_revisits);
}

// A recording played at its recorded pace goes through the live-sensor path: keyframes the mapper
// cannot take in time are dropped and counted, never queued without bound.
TEST(Map, ARecordingAtItsRecordedPaceTakesTheLiveSensorPath) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  const std::string dir = testing::MakeTempDir("realtime");
  const CommandResult run = Sightmap("map --source " + path + " --realtime --rate 30 --model " +
                                     dir + "/m.db --headless --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json summary = nlohmann::json::parse(run.out);
  const int64_t keyframes = summary.at("keyframes").get<int64_t>();
  const int64_t dropped = summary.at("dropped_frames").get<int64_t>();
  const int64_t unpaired = summary.at("unpaired_frames").get<int64_t>();
  EXPECT_EQ(summary.at("source_kind"), "oni");
  EXPECT_EQ(summary.at("reason"), "the source ended") << "not a truncated recording";
  EXPECT_GE(keyframes, 1);
  EXPECT_EQ(keyframes + dropped + unpaired, 12)
      << "every frame is mapped, or counted as dropped (behind the recorded pace) or unpaired";
  EXPECT_GE(summary.at("elapsed_s").get<double>(), 0.3) << "12 frames recorded over 0.367 s";
  EXPECT_EQ(store::Model::Open(dir + "/m.db", store::ModelOptions::ReadOnly()).NumKeyframes(),
            keyframes);
  std::printf("realtime replay of 12 frames at 30 Hz: %lld mapped, %lld dropped, %lld unpaired\n",
              static_cast<long long>(keyframes), static_cast<long long>(dropped),
              static_cast<long long>(unpaired));
}

}  // namespace
}  // namespace sightmap
