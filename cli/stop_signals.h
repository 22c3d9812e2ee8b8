// How `map` and `serve` stop on Ctrl-C or SIGTERM: the first signal asks the command to finish
// what it has in hand, a second one exits at once.
#pragma once

#include <signal.h>

#include <atomic>
#include <functional>
#include <string>
#include <thread>

namespace sightmap::cli {

// Takes SIGINT and SIGTERM away from every thread and hands them to one watcher thread, which
// may call anything, unlike a signal handler. Threads inherit the signal mask, so construct it
// before any thread starts (OpenCV's, the server's, the mapper's); a signal that comes before
// Start() waits for it. After the first signal the watcher prints `stopping_message` and calls
// `on_stop` every 100 ms until finished (a stop that raced the work's start is repeated); a
// second signal prints "<command>: second signal, exiting at once" and _exits 128 + signal
// (committed work is safe: the model's writes are transactions).
class StopSignalWatcher {
 public:
  StopSignalWatcher(std::string command, std::string stopping_message);
  ~StopSignalWatcher();
  StopSignalWatcher(const StopSignalWatcher&) = delete;
  StopSignalWatcher& operator=(const StopSignalWatcher&) = delete;

  // Starts watching; call once.
  void Start(std::function<void()> on_stop);
  // Ends the watcher thread: `on_stop` is not called after this returns (idempotent). The mask
  // stays until destruction, so a late signal cannot kill the process mid-cleanup.
  void Finish();
  // Signals received so far.
  int received() const { return received_; }

 private:
  void Watch(const std::function<void()>& on_stop);

  const std::string second_signal_message_;
  const std::string stopping_message_;
  sigset_t signals_{};
  sigset_t previous_mask_{};
  std::atomic<bool> done_{false};
  std::atomic<int> received_{0};
  std::thread thread_;
};

}  // namespace sightmap::cli
