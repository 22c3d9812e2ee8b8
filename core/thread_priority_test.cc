#include "core/thread_priority.h"

#include <algorithm>
#include <chrono>
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

}  // namespace
}  // namespace sightmap
