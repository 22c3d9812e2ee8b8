#include "core/thread_priority.h"

#include <thread>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace sightmap
