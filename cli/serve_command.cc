// sightmap serve --model M [--host 127.0.0.1] [--port 8080] [--threads N] [--max-body-mb 20]
// [--max-megapixels 25] [--timeout S]: answers phones over HTTP (see cli/locate_server.h for the
// endpoints). Prints the URL it listens on (with --port 0, the port the system chose) and serves
// until Ctrl-C or SIGTERM, then finishes the requests in hand and exits 0.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <random>
#include <string>
#include <thread>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "cli/locate_server.h"
#include "cli/stop_signals.h"
#include "core/check.h"

namespace sightmap::cli {
namespace {

bool IsLoopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

// Why label edits cannot be saved to `model_path` by this user, or "" when they can (SQLite also
// writes its journal beside the file).
std::string WhyNotWritable(const std::string& model_path) {
  if (::access(model_path.c_str(), W_OK) != 0) return "the model file is not writable by this user";
  const std::filesystem::path folder = std::filesystem::absolute(model_path).parent_path();
  if (::access(folder.c_str(), W_OK) != 0) {
    return "the model's folder is not writable by this user (SQLite writes its journal there)";
  }
  return "";
}

std::string MakeToken() {
  std::random_device random;
  char text[17];
  std::snprintf(text, sizeof(text), "%08x%08x", random(), random());
  return text;
}

}  // namespace

int RunServe(int argc, char** argv) {
  CLI::App app(
      "Serve appliance identification over HTTP: the phone page at /, the labelling page at "
      "/label, and the API: POST /locate (a JPEG or PNG photo; optional ?fx=&fy=&cx=&cy=), GET "
      "/appliances, GET /health.",
      "sightmap serve");
  std::string model_path;
  LocateServerOptions options;
  std::optional<int> timeout_s;
  auto* model_option =
      app.add_option("--model", model_path, "the model (from 'sightmap map', with labels)");
  app.add_option("--host", options.host, "address to listen on")->capture_default_str();
  app.add_option("--port", options.port, "port; 0 picks a free one (printed)")
      ->check(Within(0, 65535))
      ->capture_default_str();
  app.add_option("--threads", options.locate_threads,
                 "photos located at once (0: one per hardware thread)")
      ->check(Within(0, 256))
      ->capture_default_str();
  app.add_option("--max-body-mb", options.max_body_mb, "larger uploads get 413 [MiB]")
      ->check(Within(0.001, 4096, "MiB"))
      ->capture_default_str();
  app.add_option("--max-megapixels", options.max_megapixels,
                 "photos larger than this get 413, judged from their header before decoding")
      ->check(Within(0.01, 1000, "megapixels"))
      ->capture_default_str();
  app.add_option("--timeout", timeout_s,
                 "a client that stops sending or receiving for this long is dropped [s] "
                 "(default: 5 s sending, 20 s receiving)")
      ->check(Within(1, 3600, "s"));
  app.add_flag("--read-only", options.read_only,
               "the labelling page only shows; label edits are refused (the default when the "
               "model file is not writable)");
  app.add_option("--token", options.edit_token,
                 "label edits must carry this token (made up and printed when --host is not a "
                 "loopback address; the phone page needs none)");
  bool print_config = false;
  AddConfigOptions(app, options, print_config);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (timeout_s) {
    options.read_timeout_s = *timeout_s;
    options.write_timeout_s = *timeout_s;
  }
  if (print_config) return PrintConfig(options);
  if (const int code = RequireGiven(app, {model_option}); code >= 0) return code;
  if (!options.read_only) {
    const std::string why = WhyNotWritable(model_path);
    if (!why.empty()) {
      options.read_only = true;
      options.read_only_reason = why;
    }
  }
  if (!options.read_only && options.edit_token.empty() && !IsLoopback(options.host)) {
    options.edit_token = MakeToken();
  }

  // glibc gives threads up to 8 x cores malloc arenas and does not hand memory freed in one to
  // another: with 32 connection threads the resident size grew with every new thread that
  // allocated a photo (194 -> 216 MiB over 1,000 requests). Two arenas per locate slot.
  mallopt(M_ARENA_MAX,
          2 * std::max(1, options.locate_threads > 0
                              ? options.locate_threads
                              : static_cast<int>(std::thread::hardware_concurrency())));
  // And it raises its mmap threshold to the largest block freed, so after the first photo the
  // multi-megabyte image pyramids of feature extraction (RootSIFT's is ~5 MB a level) come from
  // the arenas and stay resident when freed: with the RootSIFT second look, 264-310 MiB after
  // 100 requests grew to 315-370 MiB after 1,000. A fixed threshold maps them and gives them back.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  StopSignalWatcher watcher(
      "sightmap serve",
      "sightmap serve: stopping (finishing the requests in hand; again to exit at once)\n");
  LocateServer server(model_path, options);
  server.Bind();
  std::cerr << "sightmap serve: loading " << model_path << "\n" << std::flush;
  server.Load(TenthsProgress("sightmap serve: loaded", "keyframes"));
  // Declared after the server, so destroyed first however this returns: the watcher never calls
  // Stop() on a server that is gone.
  struct FinishWatcher {
    StopSignalWatcher& watcher;
    ~FinishWatcher() { watcher.Finish(); }
  } finish_watcher{watcher};
  watcher.Start([&server] { server.Stop(); });
  std::cout << "sightmap serve: listening on http://" << options.host << ":" << server.port()
            << " (" << server.NumKeyframes() << " keyframes, " << server.NumLabels()
            << " labels; POST /locate, GET /appliances, GET /health; Ctrl-C stops)\n";
  const std::string url = "http://" + options.host + ":" + std::to_string(server.port());
  std::cout << "sightmap serve: phone page " << url << "/\n";
  if (options.read_only) {
    std::cout << "sightmap serve: labelling page " << url
              << "/label (read-only: " << options.read_only_reason << ")\n";
  } else if (!options.edit_token.empty()) {
    std::cout << "sightmap serve: labelling page " << url << "/label?token=" << options.edit_token
              << " (edits need the token " << options.edit_token << ")\n";
  } else {
    std::cout << "sightmap serve: labelling page " << url << "/label\n";
  }
  std::cout << std::flush;
  server.Run();
  std::cout << "sightmap serve: stopped\n" << std::flush;
  return kExitSuccess;
}

}  // namespace sightmap::cli
