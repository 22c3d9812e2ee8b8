// Crash and full-disk safety: a writer killed at random moments or stopped by a full disk leaves a
// model that opens, passes integrity_check, and holds every keyframe whole or not at all.
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <iostream>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "store/model.h"
#include "store/store_test_util.h"
#include "store/synthetic_model.h"
#include "tests/test_data.h"

namespace sightmap::store {
namespace {

constexpr int kFeaturesPerKeyframe = 300;

SyntheticKeyframeOptions WriterKeyframes() {
  SyntheticKeyframeOptions options;
  options.width = 160;
  options.height = 120;
  options.num_features = kFeaturesPerKeyframe;
  return options;
}

// Appends keyframes forever (or `limit` of them), each linked to the one before it, as mapping
// does, calling `committed` after each. Runs in a child process.
void WriteKeyframes(Model& model, const SyntheticKeyframeOptions& options, int limit = -1,
                    const std::function<void()>& committed = nullptr) {
  const SessionId session = model.BeginSession({});
  const std::vector<KeyframeInfo> existing = model.Keyframes();
  KeyframeId previous = existing.empty() ? KeyframeId() : existing.back().id;
  for (int i = static_cast<int>(existing.size()); limit < 0 || i < limit; ++i) {
    KeyframeRecord keyframe = MakeSyntheticKeyframe(session, i, options);
    if (previous.valid()) {
      LinkRecord odometry;
      odometry.from = previous;
      odometry.to_in_from.translation() = Eigen::Vector3d(options.step_m, 0, 0);
      keyframe.links.push_back(odometry);
    }
    previous = model.AddKeyframe(keyframe);
    if (committed) committed();
  }
}

// Every keyframe has its images, all its features and the link from its predecessor.
void ExpectEveryKeyframeWhole(const Model& model, int expected_features) {
  EXPECT_EQ(model.IntegrityCheck(), "ok");
  const std::vector<KeyframeInfo> keyframes = model.Keyframes();
  std::vector<int> incoming(keyframes.size(), 0);
  for (const LinkRecord& link : model.Links()) {
    for (size_t i = 0; i < keyframes.size(); ++i) incoming[i] += link.to == keyframes[i].id;
  }
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const KeyframeId id = keyframes[i].id;
    EXPECT_EQ(keyframes[i].num_features, expected_features) << "keyframe " << id.value();
    EXPECT_EQ(model.LoadFeatures(id).keypoints.size(), static_cast<size_t>(expected_features));
    EXPECT_EQ(model.LoadDepth(id).cols, keyframes[i].intrinsics.width);
    EXPECT_EQ(model.LoadColor(id).rows, keyframes[i].intrinsics.height);
    EXPECT_EQ(incoming[i], i == 0 ? 0 : 1) << "keyframe " << id.value() << " lost its link";
  }
}

TEST(Durability, SigkillAtTwentyRandomMomentsLeavesWholeKeyframes) {
  const std::string path = testing::MakeTempDir("store_kill") + "/model.db";
  const unsigned seed = static_cast<unsigned>(std::random_device{}());
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> delay_ms(0, 60);
  SCOPED_TRACE("seed " + std::to_string(seed));
  int64_t previous_count = 0;
  for (int kill = 0; kill < 20; ++kill) {
    // The writer says through a pipe when its first keyframe is committed; the kill lands a random
    // moment after that, so it hits writing rather than start-up however loaded the machine is.
    int committed[2];
    ASSERT_EQ(pipe(committed), 0);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(committed[0]);
      try {
        Model model = Model::Open(path);
        WriteKeyframes(model, WriterKeyframes(), -1, [fd = committed[1]] {
          const char byte = 1;
          if (write(fd, &byte, 1) < 0) _exit(4);
        });
      } catch (...) {
        _exit(3);
      }
      _exit(0);
    }
    close(committed[1]);
    pollfd ready{committed[0], POLLIN, 0};
    ASSERT_EQ(poll(&ready, 1, 30'000), 1) << "the writer committed nothing within 30 s";
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms(random)));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    close(committed[0]);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the writer stopped by itself, status " << status;

    Model model = Model::Open(path);
    ExpectEveryKeyframeWhole(model, kFeaturesPerKeyframe);
    const int64_t count = model.NumKeyframes();
    EXPECT_GT(count, previous_count) << "committed keyframes were lost";
    previous_count = count;
    if (HasFailure()) break;
  }
  std::cout << "[ info ] " << previous_count << " keyframes written across 20 kills\n";
  // Every writer committed at least one keyframe before its kill.
  EXPECT_GE(previous_count, 20);
  Model model = Model::Open(path);
  EXPECT_GE(model.MarkRunningSessionsInterrupted(1), 1);
}

TEST(Durability, FullDiskEndsTheWriterWithAClearErrorAndKeepsTheModel) {
  const std::string path = testing::MakeTempDir("store_full") + "/model.db";
  { Model::Open(path); }
  SyntheticKeyframeOptions big;  // 640x480, the size mapping writes
  big.num_features = 1000;
  const testing::ChildOutcome outcome = testing::RunInChild([&] {
    // Writes past the limit fail with EFBIG instead of killing the process.
    signal(SIGXFSZ, SIG_IGN);
    rlimit limit{};
    limit.rlim_cur = limit.rlim_max = 2 * 1024 * 1024;
    SIGHTMAP_CHECK(setrlimit(RLIMIT_FSIZE, &limit) == 0, "setrlimit failed");
    Model model = Model::Open(path);
    try {
      WriteKeyframes(model, big, 1000);
    } catch (const Error&) {
      // The connection that hit the full disk stays usable: it still reads every keyframe.
      SIGHTMAP_CHECK(model.NumKeyframes() >= 1 && model.IntegrityCheck() == "ok",
                     "the model became unusable after the full disk");
      throw;
    }
  });
  EXPECT_EQ(outcome.exit_code, 3) << outcome.message;
  std::cout << "[ info ] writer stopped with: " << outcome.message << "\n";
  EXPECT_NE(outcome.message.find("free disk space"), std::string::npos) << outcome.message;
  EXPECT_EQ(outcome.message.find('\n'), std::string::npos) << outcome.message;

  Model model = Model::Open(path);
  const int64_t written = model.NumKeyframes();
  EXPECT_GE(written, 1);
  EXPECT_LT(written, 1000);
  ExpectEveryKeyframeWhole(model, 1000);
  // With space again, the model takes more keyframes.
  KeyframeRecord more = MakeSyntheticKeyframe(model.BeginSession({}), 0, big);
  LinkRecord link;
  link.from = model.Keyframes().back().id;
  more.links.push_back(link);
  model.AddKeyframe(more);
  EXPECT_EQ(model.NumKeyframes(), written + 1);
  EXPECT_EQ(model.IntegrityCheck(), "ok");
}

}  // namespace
}  // namespace sightmap::store
