#include "cli/stop_signals.h"

#include <pthread.h>
#include <unistd.h>

#include <ctime>
#include <iostream>
#include <utility>

#include "core/check.h"

namespace sightmap::cli {

StopSignalWatcher::StopSignalWatcher(std::string command, std::string stopping_message)
    : second_signal_message_("\n" + command + ": second signal, exiting at once\n"),
      stopping_message_(std::move(stopping_message)) {
  sigemptyset(&signals_);
  sigaddset(&signals_, SIGINT);
  sigaddset(&signals_, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals_, &previous_mask_);
}

StopSignalWatcher::~StopSignalWatcher() {
  Finish();
  pthread_sigmask(SIG_SETMASK, &previous_mask_, nullptr);
}

void StopSignalWatcher::Start(std::function<void()> on_stop) {
  SIGHTMAP_CHECK(!thread_.joinable(), "StopSignalWatcher::Start called twice");
  thread_ = std::thread([this, on_stop = std::move(on_stop)] { Watch(on_stop); });
}

void StopSignalWatcher::Finish() {
  done_ = true;
  if (thread_.joinable()) thread_.join();
}

void StopSignalWatcher::Watch(const std::function<void()>& on_stop) {
  while (!done_) {
    const timespec poll{0, 100'000'000};
    const int signal_number = sigtimedwait(&signals_, nullptr, &poll);
    if (signal_number > 0) {
      if (++received_ >= 2) {
        [[maybe_unused]] const ssize_t ignored =
            ::write(STDERR_FILENO, second_signal_message_.data(), second_signal_message_.size());
        _exit(128 + signal_number);
      }
      std::cerr << stopping_message_ << std::flush;
    }
    if (received_ > 0) on_stop();
  }
}

}  // namespace sightmap::cli
