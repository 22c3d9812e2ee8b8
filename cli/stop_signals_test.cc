#include "cli/stop_signals.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace sightmap::cli {
namespace {

bool WaitFor(const std::atomic<int>& value, int at_least) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (value < at_least && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return value >= at_least;
}

TEST(StopSignalWatcher, TheFirstSignalAsksToStopAndRepeatsUntilFinished) {
  std::atomic<int> stops{0};
  {
    StopSignalWatcher watcher("test", "test: stopping\n");
    watcher.Start([&stops] { ++stops; });
    EXPECT_EQ(stops, 0);
    ASSERT_EQ(::kill(::getpid(), SIGTERM), 0);  // process-directed: only the watcher takes it
    ASSERT_TRUE(WaitFor(stops, 2)) << "on_stop was not called again";
    EXPECT_EQ(watcher.received(), 1);
    watcher.Finish();
    const int after_finish = stops;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    EXPECT_EQ(stops, after_finish) << "on_stop was called after Finish";
  }
  // The mask is restored: SIGTERM is deliverable again (checked without sending one).
  sigset_t mask;
  pthread_sigmask(SIG_SETMASK, nullptr, &mask);
  EXPECT_FALSE(sigismember(&mask, SIGTERM));
  EXPECT_FALSE(sigismember(&mask, SIGINT));
}

TEST(StopSignalWatcher, ASignalBeforeStartWaitsForIt) {
  std::atomic<int> stops{0};
  StopSignalWatcher watcher("test", "test: stopping\n");
  ASSERT_EQ(::kill(::getpid(), SIGINT), 0);  // blocked, so pending, not fatal
  watcher.Start([&stops] { ++stops; });
  EXPECT_TRUE(WaitFor(stops, 1));
}

TEST(StopSignalWatcherDeathTest, ASecondSignalExitsAtOnce) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        StopSignalWatcher watcher("sightmap test", "stopping\n");
        watcher.Start([] {});  // a stop that never finishes
        ::kill(::getpid(), SIGINT);
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
        ::kill(::getpid(), SIGTERM);
        std::this_thread::sleep_for(std::chrono::seconds(10));
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(128 + SIGTERM), "sightmap test: second signal, exiting at once");
}

}  // namespace
}  // namespace sightmap::cli
