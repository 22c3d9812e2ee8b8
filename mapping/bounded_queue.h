// A bounded multi-producer multi-consumer queue joining the stages of a mapping session (Basalt's
// pipeline style): a producer either waits for room (a replay, which must not lose a frame) or
// never waits and drops the oldest item when the queue is full (a live sensor: the consumer gets
// the newest frames, and the producer counts the drop).
// Close() marks the end of the stream: producers stop, consumers drain what is left and then see
// the end.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

#include "core/check.h"

namespace sightmap::mapping {

template <typename T>
class BoundedQueue {
 public:
  explicit BoundedQueue(size_t capacity) : capacity_(capacity) {
    if (capacity_ == 0) SIGHTMAP_THROW(InvalidArgument, "a bounded queue needs a capacity >= 1");
  }
  BoundedQueue(const BoundedQueue&) = delete;
  BoundedQueue& operator=(const BoundedQueue&) = delete;

  // Waits for room; false (and `item` is dropped) when the queue was closed meanwhile.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }

  enum class PushResult { kQueued, kDroppedOldest, kClosed };

  // Never waits: when the queue is full its oldest item is dropped to make room, so a consumer
  // that falls behind a live sensor always gets the newest items (the caller counts the drop).
  PushResult PushNewest(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (closed_) return PushResult::kClosed;
    PushResult result = PushResult::kQueued;
    if (items_.size() >= capacity_) {
      items_.pop_front();
      result = PushResult::kDroppedOldest;
    }
    items_.push_back(std::move(item));
    lock.unlock();
    not_empty_.notify_one();
    return result;
  }

  enum class PopResult { kItem, kTimeout, kEnd };

  // Waits up to `timeout` for an item. kEnd once the queue is closed and drained.
  template <typename Rep, typename Period>
  PopResult Pop(T* item, std::chrono::duration<Rep, Period> timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!not_empty_.wait_for(lock, timeout, [&] { return closed_ || !items_.empty(); })) {
      return PopResult::kTimeout;
    }
    if (items_.empty()) return PopResult::kEnd;
    *item = std::move(items_.front());
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return PopResult::kItem;
  }

  // Waits for an item; std::nullopt once the queue is closed and drained.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    std::optional<T> item(std::move(items_.front()));
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }

  // Ends the stream: waiting producers return false, consumers drain then see the end.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
  }

  // Removes every queued item; returns how many there were.
  size_t Clear() {
    size_t removed;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      removed = items_.size();
      items_.clear();
    }
    not_full_.notify_all();
    return removed;
  }

  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }
  size_t capacity() const { return capacity_; }
  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }

 private:
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_full_;
  std::condition_variable not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
};

}  // namespace sightmap::mapping
