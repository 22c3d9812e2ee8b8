#include "core/thread_priority.h"

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/core/utility.hpp>

namespace sightmap {
namespace {

TEST(ThreadPriorityTest, LowersOnlyTheCallingThreadAndCapsAt19) {
  const int main_nice = ThisThreadsNice();
  int lowered = -100;
  int capped = -100;
  int inherited = -100;
  std::thread worker([&] {
    ASSERT_TRUE(LowerThisThreadsPriority(3));
    lowered = ThisThreadsNice();
    // A thread started now inherits the lowered priority.
    std::thread child([&] { inherited = ThisThreadsNice(); });
    child.join();
    ASSERT_TRUE(LowerThisThreadsPriority(40));
    capped = ThisThreadsNice();
  });
  worker.join();
  EXPECT_EQ(lowered, std::min(19, main_nice + 3));
  EXPECT_EQ(inherited, lowered);
  EXPECT_EQ(capped, 19);
  EXPECT_EQ(ThisThreadsNice(), main_nice);  // the caller's own thread is untouched
  EXPECT_TRUE(LowerThisThreadsPriority(0));
  EXPECT_EQ(ThisThreadsNice(), main_nice);
}

TEST(ThreadPriorityTest, OpenCVsWorkersKeepTheirPriorityWhenALoweredThreadRunsParallelWork) {
  const int main_nice = ThisThreadsNice();
  std::mutex mutex;
  std::map<std::thread::id, int> nice_by_thread;
  std::thread::id lowered_thread;
  std::thread worker([&] {
    ASSERT_TRUE(LowerThisThreadsPriority(5));
    lowered_thread = std::this_thread::get_id();
    cv::parallel_for_(cv::Range(0, 100), [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        std::lock_guard<std::mutex> lock(mutex);
        nice_by_thread[std::this_thread::get_id()] = ThisThreadsNice();
      }
    });
  });
  worker.join();
  for (const auto& [thread, nice] : nice_by_thread) {
    EXPECT_EQ(nice, thread == lowered_thread ? std::min(19, main_nice + 5) : main_nice);
  }
  // 100 stripes of 2 ms: OpenCV's workers took part (on a machine with more than one core).
  if (cv::getNumThreads() > 1) {
    EXPECT_GT(nice_by_thread.size(), 1u);
  }
}

TEST(ThreadPriorityTest, LowersTheThreadsOfAName) {
  const int main_nice = ThisThreadsNice();
  std::mutex mutex;
  std::condition_variable measure;
  bool go = false;
  std::atomic<int> named_threads{0};
  const auto run = [&](const char* name, int* nice) {
    pthread_setname_np(pthread_self(), name);
    ++named_threads;
    std::unique_lock<std::mutex> lock(mutex);
    measure.wait(lock, [&] { return go; });
    *nice = ThisThreadsNice();
  };
  int named_nice = -100;
  int other_nice = -100;
  std::thread named([&] { run("rasterpipe-0", &named_nice); });
  std::thread other([&] { run("sightmap-other", &other_nice); });
  while (named_threads < 2) std::this_thread::yield();
  const int target = std::min(19, main_nice + 4);
  const int lowered = LowerThreadsNamed("rasterpipe-", main_nice + 4);
  const int raised_back = LowerThreadsNamed("rasterpipe-", main_nice + 2);
  {
    std::lock_guard<std::mutex> lock(mutex);
    go = true;
  }
  measure.notify_all();
  named.join();
  other.join();
  EXPECT_EQ(lowered, target > main_nice ? 1 : 0);
  EXPECT_EQ(raised_back, 0);  // a nice value is only ever raised
  EXPECT_EQ(named_nice, target);
  EXPECT_EQ(other_nice, main_nice);
  EXPECT_EQ(ThisThreadsNice(), main_nice);
  EXPECT_EQ(LowerThreadsNamed("no-such-thread-", 19), 0);
}

}  // namespace
}  // namespace sightmap
