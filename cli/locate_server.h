// The HTTP face of the matching phase (`sightmap serve`): phones POST a photo and get back the
// Locator's answer. cpp-httplib stays inside locate_server.cc.
//
//   POST /locate[?fx=&fy=&cx=&cy=]  body: a JPEG or PNG photo -> the Locator's JSON (ToJson)
//   GET  /appliances                the model's labels with their world points
//   GET  /health                    status, keyframes, labels, counters, request times
//   GET  /  and  /label             the phone page and the labelling page (cli/web_assets.h)
//   GET  /api/status | /api/keyframes | /api/keyframes/ID/image.jpg[?max_side=N]
//        /api/keyframes/ID/labels | /api/labels          what the labelling page reads
//   POST /api/labels, PATCH|DELETE /api/labels/ID        its edits (cli/label_service.h): 403
//        when the server is read-only, 401 without the edit token when one is set
//
// The photo is the request body whatever its Content-Type, or the file field "photo" (else the
// first file) of a multipart form. Bad uploads are answered with 4xx and {"error": "...",
// "status": N}: an empty body 400, a body that is not a JPEG or PNG 415, a photo whose header
// states more than max_megapixels 413 (read from its header, before decoding), one cut short (no
// end marker) or that does not decode 400, a declared Content-Length that is malformed 400 or over
// max_body_mb 413 (at once, before the body is read), a POST with neither a Content-Length nor
// chunked encoding 411.
#pragma once

#include <memory>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "cli/label_service.h"
#include "identify/locator.h"

namespace sightmap::cli {

struct LocateServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0 = a free port chosen by the system (see LocateServer::port())
  // Photos located at once: each Locate uses one core for ~100 ms, so more than the machine's
  // cores only queues in memory. 0 = the hardware's threads.
  int locate_threads = 0;
  // HTTP connections served at once (a keep-alive connection holds a worker while idle); 0 =
  // max(32, 8 x locate_threads): threads are cheap, and a slow client holds one. Connections beyond
  // this and max_queued_connections wait in the kernel's listen backlog instead of in memory.
  int connection_threads = 0;
  int max_queued_connections = 64;
  double max_body_mb = 20.0;     // request bodies above this are refused with 413 [MiB]
  double max_megapixels = 25.0;  // photos above this are refused from their header [Mpx]
  // A client that stops sending for this long is dropped: short, so that clients which send
  // their headers and then nothing cannot hold the connection threads for long [s].
  int read_timeout_s = 5;
  int write_timeout_s = 20;      // [s]
  int keep_alive_timeout_s = 2;  // idle keep-alive connections are closed after this [s]
  // The model's labels are re-read this often while serving, so a `sightmap label add` on the
  // served model answers phones without a restart (0 = never) [s].
  double label_refresh_s = 2.0;
  // One line per request on stderr: time, client, method, path, status, bytes, milliseconds.
  bool log_requests = true;
  // Label edits are refused (403, with read_only_reason) and the labelling page hides its
  // editing controls.
  bool read_only = false;
  std::string read_only_reason = "the server was started with --read-only";
  // When set, label edits must carry it (header X-Sightmap-Token, or ?token=): for a server other
  // machines can reach. Reading, and the phone page, need none.
  std::string edit_token;
  identify::LocatorOptions locator;
  // Its editable and read_only_reason are the server's: set from read_only above.
  LabelServiceOptions labels;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const LocateServerOptions& options);
void from_json(const nlohmann::json& json, LocateServerOptions& options);

class LocateServer {
 public:
  // Sets up the routes; nothing is read or bound yet. Bind() first, then Load(), then Run(): a
  // busy port is reported at once, not after seconds of loading a large model (connections made
  // while it loads wait in the listen queue).
  LocateServer(const std::string& model_path, const LocateServerOptions& options);
  ~LocateServer();
  LocateServer(const LocateServer&) = delete;
  LocateServer& operator=(const LocateServer&) = delete;

  // Binds host:port (port 0: any free port). Throws Error when the address cannot be bound.
  void Bind();
  int port() const;  // the bound port, after Bind()
  // Loads the model read-only and builds the Locator once (seconds for a large model). Throws
  // sightmap::Error when the model cannot be used.
  void Load(const identify::LoadProgress& progress = {});
  // Serves until Stop(); returns after the workers have finished their requests. Re-reads the
  // labels every label_refresh_s meanwhile.
  void Run();
  // Thread-safe; makes Run() return. Callable before Run() starts.
  void Stop();

  // The loaded model's, after Load().
  size_t NumKeyframes() const;
  size_t NumLabels() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::cli
