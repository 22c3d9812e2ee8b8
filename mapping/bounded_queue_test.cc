#include "mapping/bounded_queue.h"

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace sightmap::mapping {
namespace {

using namespace std::chrono_literals;

TEST(BoundedQueue, PushNewestDropsTheOldestWhenFullAndKeepsOrder) {
  using PushResult = BoundedQueue<int>::PushResult;
  BoundedQueue<int> queue(2);
  EXPECT_EQ(queue.PushNewest(1), PushResult::kQueued);
  EXPECT_EQ(queue.PushNewest(2), PushResult::kQueued);
  EXPECT_EQ(queue.PushNewest(3), PushResult::kDroppedOldest) << "a live frame never waits";
  EXPECT_EQ(queue.size(), 2u);
  EXPECT_EQ(queue.Pop(), 2);
  EXPECT_EQ(queue.PushNewest(4), PushResult::kQueued);
  EXPECT_EQ(queue.Pop(), 3);
  EXPECT_EQ(queue.Pop(), 4);
  queue.Close();
  EXPECT_EQ(queue.PushNewest(5), PushResult::kClosed);
}

TEST(BoundedQueue, PushWaitsForRoomUntilAnItemIsTaken) {
  BoundedQueue<int> queue(1);
  ASSERT_TRUE(queue.Push(1));
  std::atomic<bool> returned{false};
  std::thread producer([&] {
    EXPECT_TRUE(queue.Push(2));
    returned = true;
  });
  // A correct Push cannot return before the Pop below, however slow the machine; one that does
  // not wait returns at once and is caught here.
  std::this_thread::sleep_for(100ms);
  EXPECT_FALSE(returned.load()) << "Push returned while the queue was full";
  EXPECT_EQ(queue.size(), 1u);
  EXPECT_EQ(queue.Pop(), 1);
  producer.join();
  EXPECT_TRUE(returned.load());
  EXPECT_EQ(queue.Pop(), 2);
}

TEST(BoundedQueue, PushWaitsForRoomSoAReplayLosesNothing) {
  BoundedQueue<int> queue(1);
  constexpr int kItems = 200;
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) ASSERT_TRUE(queue.Push(i));
    queue.Close();
  });
  std::vector<int> received;
  while (std::optional<int> item = queue.Pop()) {
    EXPECT_LE(queue.size(), 1u);
    received.push_back(*item);
  }
  producer.join();
  ASSERT_EQ(received.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) EXPECT_EQ(received[static_cast<size_t>(i)], i);
}

TEST(BoundedQueue, CloseReleasesAWaitingProducerAndConsumersDrain) {
  BoundedQueue<int> queue(1);
  ASSERT_TRUE(queue.Push(7));
  bool pushed = true;
  std::thread producer([&] { pushed = queue.Push(8); });  // waits: the queue is full
  std::this_thread::sleep_for(50ms);
  queue.Close();
  producer.join();
  EXPECT_FALSE(pushed);
  int item = 0;
  EXPECT_EQ(queue.Pop(&item, 10ms), BoundedQueue<int>::PopResult::kItem);
  EXPECT_EQ(item, 7);
  EXPECT_EQ(queue.Pop(&item, 10ms), BoundedQueue<int>::PopResult::kEnd);
  EXPECT_EQ(queue.PushNewest(9), BoundedQueue<int>::PushResult::kClosed);
}

TEST(BoundedQueue, PopTimesOutOnAnEmptyOpenQueue) {
  BoundedQueue<int> queue(3);
  int item = 0;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(queue.Pop(&item, 30ms), BoundedQueue<int>::PopResult::kTimeout);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 25ms);
  EXPECT_THROW(BoundedQueue<int>(0), InvalidArgument);
}

}  // namespace
}  // namespace sightmap::mapping
