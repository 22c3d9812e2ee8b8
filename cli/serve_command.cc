// sightmap serve --model M [--host 127.0.0.1] [--port 8080] [--threads N] [--max-body-mb 20]
// [--max-megapixels 25] [--timeout S]: answers phones over HTTP (see cli/locate_server.h for the
// endpoints). Prints the URL it listens on (with --port 0, the port the system chose) and serves
// until Ctrl-C or SIGTERM, then finishes the requests in hand and exits 0.
#include <pthread.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <ctime>
#include <functional>
#include <iostream>
#include <string>
#include <thread>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "cli/locate_server.h"
#include "core/check.h"

namespace sightmap::cli {
namespace {

// Takes SIGINT and SIGTERM away from every thread (they inherit the mask, so it must be built
// before any thread starts, OpenCV's and the server's included) and hands them to one watcher
// thread, which may call anything, unlike a signal handler. After the first signal it calls
// `on_stop` every 100 ms until destroyed (a stop that raced the server's start is repeated); a
// second signal exits at once.
class StopSignalWatcher {
 public:
  StopSignalWatcher() {
    sigemptyset(&signals_);
    sigaddset(&signals_, SIGINT);
    sigaddset(&signals_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &signals_, &previous_mask_);
  }
  ~StopSignalWatcher() {
    Finish();
    pthread_sigmask(SIG_SETMASK, &previous_mask_, nullptr);
  }
  StopSignalWatcher(const StopSignalWatcher&) = delete;
  StopSignalWatcher& operator=(const StopSignalWatcher&) = delete;

  // Ends the watcher thread: `on_stop` is not called after this returns (idempotent).
  void Finish() {
    done_ = true;
    if (thread_.joinable()) thread_.join();
  }

  void Start(std::function<void()> on_stop) {
    thread_ = std::thread([this, on_stop = std::move(on_stop)] {
      int received = 0;
      while (!done_) {
        const timespec poll{0, 100'000'000};
        const int signal_number = sigtimedwait(&signals_, nullptr, &poll);
        if (signal_number > 0) {
          if (++received >= 2) {
            static const char kMessage[] = "sightmap serve: second signal, exiting at once\n";
            [[maybe_unused]] const ssize_t ignored = ::write(2, kMessage, sizeof(kMessage) - 1);
            _exit(128 + signal_number);
          }
          std::cerr << "sightmap serve: stopping (finishing the requests in hand; again to exit "
                       "at once)\n"
                    << std::flush;
        }
        if (received > 0) on_stop();
      }
    });
  }

 private:
  sigset_t signals_{};
  sigset_t previous_mask_{};
  std::atomic<bool> done_{false};
  std::thread thread_;
};

}  // namespace

int RunServe(int argc, char** argv) {
  CLI::App app(
      "Serve appliance identification over HTTP: POST /locate (a JPEG or PNG photo; optional "
      "?fx=&fy=&cx=&cy=), GET /appliances, GET /health.",
      "sightmap serve");
  std::string model_path;
  LocateServerOptions options;
  int timeout_s = options.read_timeout_s;
  app.add_option("--model", model_path, "the model (from 'sightmap map', with labels)")->required();
  app.add_option("--host", options.host, "address to listen on")->capture_default_str();
  app.add_option("--port", options.port, "port; 0 picks a free one (printed)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--threads", options.locate_threads,
                 "photos located at once (0: one per hardware thread)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  app.add_option("--max-body-mb", options.max_body_mb, "larger uploads get 413 [MiB]")
      ->check(CLI::Range(0.001, 4096.0))
      ->capture_default_str();
  app.add_option("--max-megapixels", options.max_megapixels,
                 "photos larger than this get 413, judged from their header before decoding")
      ->check(CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  app.add_option("--timeout", timeout_s,
                 "a client that stops sending or receiving for this long is dropped [s]")
      ->check(CLI::Range(1, 3600))
      ->capture_default_str();
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  options.read_timeout_s = timeout_s;
  options.write_timeout_s = timeout_s;

  StopSignalWatcher watcher;  // before any thread exists
  std::cerr << "sightmap serve: loading " << model_path << "\n" << std::flush;
  LocateServer server(model_path, options);
  server.Bind();
  // Declared after the server, so destroyed first however this returns: the watcher never calls
  // Stop() on a server that is gone.
  struct FinishWatcher {
    StopSignalWatcher& watcher;
    ~FinishWatcher() { watcher.Finish(); }
  } finish_watcher{watcher};
  watcher.Start([&server] { server.Stop(); });
  std::cout << "sightmap serve: listening on http://" << options.host << ":" << server.port()
            << " (" << server.NumKeyframes() << " keyframes, " << server.NumLabels()
            << " labels; POST /locate, GET /appliances, GET /health; Ctrl-C stops)\n"
            << std::flush;
  server.Run();
  std::cout << "sightmap serve: stopped\n" << std::flush;
  return kExitSuccess;
}

}  // namespace sightmap::cli
