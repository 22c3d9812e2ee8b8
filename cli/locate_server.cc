#include "cli/locate_server.h"

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/label_service.h"
#include "cli/web_assets.h"
#include "core/check.h"
#include "core/options_json.h"
#include "core/statistics.h"
#include "core/timing.h"
#include "identify/photo.h"
#include "store/model.h"

// Last: httplib.h pulls in <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace sightmap::cli {
namespace {

constexpr const char* kJson = "application/json";

// httplib's ThreadPool queues without limit; this one makes the accepting thread wait when
// `max_pending` connections are being served or queued, so a burst waits in the kernel's listen
// backlog instead of in memory.
class BoundedTaskQueue : public httplib::TaskQueue {
 public:
  BoundedTaskQueue(size_t threads, size_t max_pending)
      : pool_(threads), max_pending_(max_pending) {}

  void enqueue(std::function<void()> fn) override {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      room_.wait(lock, [&] { return pending_ < max_pending_; });
      ++pending_;
    }
    pool_.enqueue([this, fn = std::move(fn)] {
      fn();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        --pending_;
      }
      room_.notify_one();
    });
  }

  void shutdown() override { pool_.shutdown(); }

 private:
  httplib::ThreadPool pool_;
  const size_t max_pending_;
  std::mutex mutex_;
  std::condition_variable room_;
  size_t pending_ = 0;
};

}  // namespace

// At most `count` holders at once (C++17 has no std::counting_semaphore). Outside the anonymous
// namespace because LocateServer::Impl holds one.
class Slots {
 public:
  explicit Slots(int count) : free_(count) {}
  class Hold {
   public:
    explicit Hold(Slots& slots) : slots_(slots) {
      std::unique_lock<std::mutex> lock(slots_.mutex_);
      slots_.freed_.wait(lock, [&] { return slots_.free_ > 0; });
      --slots_.free_;
    }
    ~Hold() {
      {
        std::lock_guard<std::mutex> lock(slots_.mutex_);
        ++slots_.free_;
      }
      slots_.freed_.notify_one();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    Slots& slots_;
  };

 private:
  std::mutex mutex_;
  std::condition_variable freed_;
  int free_;
};

namespace {

void Reply(httplib::Response& response, int status, const nlohmann::json& body) {
  response.status = status;
  // Messages quote what the client sent ("fx=3\xff is not a number"): bytes that are not UTF-8
  // become U+FFFD instead of failing the answer (the fuzzer found that 500).
  response.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), kJson);
}

void Refuse(httplib::Response& response, int status, const std::string& message) {
  Reply(response, status, {{"error", message}, {"status", status}});
}

// The answer to a refused photo: 415 when it is no image, 413 when too large, else 400.
int StatusFor(identify::PhotoProblem problem) {
  switch (problem) {
    case identify::PhotoProblem::kNotAnImage:
      return 415;
    case identify::PhotoProblem::kTooLarge:
      return 413;
    case identify::PhotoProblem::kTooSmall:
    case identify::PhotoProblem::kTruncated:
    case identify::PhotoProblem::kCorrupt:
      return 400;
  }
  return 400;
}

int HardwareThreads() { return std::max(1u, std::thread::hardware_concurrency()); }

// fx, fy, cx, cy from the query string: all four or none. Throws InvalidArgument with the reason.
std::optional<Intrinsics> IntrinsicsFromQuery(const httplib::Request& request, int width,
                                              int height) {
  const char* names[] = {"fx", "fy", "cx", "cy"};
  int given = 0;
  for (const char* name : names) given += request.has_param(name) ? 1 : 0;
  if (given == 0) return std::nullopt;
  if (given != 4) {
    SIGHTMAP_THROW(InvalidArgument,
                   "give all of fx, fy, cx, cy (pixels of the photo as shown upright) or none");
  }
  double values[4];
  for (int i = 0; i < 4; ++i) {
    const std::string text = request.get_param_value(names[i]);
    char* end = nullptr;
    values[i] = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(values[i])) {
      SIGHTMAP_THROW(InvalidArgument, names[i] << "=" << text << " is not a number");
    }
  }
  const Intrinsics intrinsics =
      Intrinsics::FromPinhole(width, height, values[0], values[1], values[2], values[3]);
  std::string why;
  if (!intrinsics.Check(&why)) SIGHTMAP_THROW(InvalidArgument, "bad intrinsics: " << why);
  return intrinsics;
}

// When the request on this worker thread reached routing (httplib hands a connection's requests
// to one worker, and calls the pre-routing handler and the logger on it).
thread_local std::optional<std::chrono::steady_clock::time_point> request_start;

// A plain decimal number (a declared Content-Length, ?max_side=), or nothing for "-5", "12abc", ""
// or one too long to be a size.
std::optional<uint64_t> ParsePlainDecimal(const std::string& text) {
  if (text.empty() || text.size() > 18) return std::nullopt;
  for (const char c : text) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
  }
  return std::stoull(text);
}

// SO_REUSEADDR (a restarted server binds at once) without httplib's default SO_REUSEPORT: a second
// server on the same port must fail at start, not share the port's connections with the first.
void ReuseAddressOnly(int socket) {
  const int yes = 1;
  setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
}

// Why binding host:port fails, as errno (0 when it does not, or the address does not resolve):
// httplib only says that it failed.
int BindErrno(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0) return 0;
  int error = 0;
  const int socket_fd = socket(found->ai_family, found->ai_socktype, found->ai_protocol);
  if (socket_fd >= 0) {
    ReuseAddressOnly(socket_fd);
    if (bind(socket_fd, found->ai_addr, found->ai_addrlen) != 0) error = errno;
    close(socket_fd);
  }
  freeaddrinfo(found);
  return error;
}

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

// Compares in time independent of where the texts differ, so the token cannot be guessed byte by
// byte from response times.
bool SameSecret(const std::string& given, const std::string& secret) {
  unsigned char differ = given.size() == secret.size() ? 0 : 1;
  for (size_t i = 0; i < given.size(); ++i) {
    differ |= static_cast<unsigned char>(given[i] ^ secret[i % std::max<size_t>(1, secret.size())]);
  }
  return differ == 0;
}

int64_t PathId(const httplib::Request& request) { return std::stoll(request.matches[1].str()); }

// Runs `answer` and sends its JSON, or the ServiceError's status and message (counted in
// `refused`).
template <typename Answer>
void ReplyWith(httplib::Response& response, std::atomic<int64_t>& refused, Answer answer) {
  try {
    Reply(response, 200, answer());
    return;
  } catch (const ServiceError& e) {
    Refuse(response, e.status(), e.what());
  } catch (const InvalidArgument& e) {
    Refuse(response, 400, e.what());
  } catch (const Error& e) {
    // The model could not be read or written: another writer holding it, a full disk.
    Refuse(response, 503, std::string(e.what()) + " (then try again)");
  }
  ++refused;
}

nlohmann::json ParseBody(const httplib::Request& request) {
  nlohmann::json body = nlohmann::json::parse(request.body, nullptr, /*allow_exceptions=*/false);
  if (body.is_discarded()) throw ServiceError(400, "the request body is not JSON");
  return body;
}

}  // namespace

bool LocateServerOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (host.empty())
    why << "host must not be empty";
  else if (port < 0 || port > 65535)
    why << "port must be in [0, 65535]";
  else if (locate_threads < 0 || connection_threads < 0)
    why << "threads must not be negative";
  else if (max_queued_connections < 0)
    why << "max_queued_connections must not be negative";
  else if (!(max_body_mb > 0.0 && max_body_mb <= 4096.0))
    why << "max_body_mb must be in (0, 4096]";
  else if (!(max_megapixels > 0.0 && max_megapixels <= 1000.0))
    why << "max_megapixels must be in (0, 1000]";
  else if (read_timeout_s < 1 || write_timeout_s < 1 || keep_alive_timeout_s < 1)
    why << "timeouts must be at least 1 s";
  else if (!(label_refresh_s >= 0.0))
    why << "label_refresh_s must not be negative";
  else if (read_only && read_only_reason.empty())
    why << "a read-only server needs a read_only_reason to give";
  if (why.tellp() == 0) {
    std::string nested;
    if (!locator.Check(&nested)) {
      why << "locator: " << nested;
    } else if (!labels.Check(&nested)) {
      why << "labels: " << nested;
    } else {
      return true;
    }
  }
  if (error != nullptr) *error = why.str();
  return false;
}

struct LocateServer::Impl {
  LocateServerOptions options;
  std::string model_path;
  std::unique_ptr<identify::Locator> locator;
  std::unique_ptr<LabelService> label_service;
  int locate_threads = 1;
  std::unique_ptr<Slots> locate_slots;
  httplib::Server server;
  int port = -1;
  std::atomic<bool> stop_requested{false};
  std::atomic<int64_t> located{0};
  std::atomic<int64_t> refused{0};
  // Every answered request, for /health: counts and the time of the newest ones.
  mutable std::mutex requests_mutex;
  int64_t requests = 0;
  int64_t errors = 0;  // answered 4xx or 5xx
  std::deque<double> recent_ms;
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  // The label watcher sleeps on this until the next refresh or Stop().
  std::mutex watch_mutex;
  std::condition_variable watch_wakeup;

  void WatchLabels();
  // Marks the server stopping and wakes the label watcher (httplib's own stop is separate).
  void RequestStop() {
    {
      const std::lock_guard<std::mutex> lock(watch_mutex);
      stop_requested = true;
    }
    watch_wakeup.notify_all();
  }

  // Refuses a declared body length that is malformed (400) or over the limit (413) before the
  // body is read; starts the request's clock.
  httplib::Server::HandlerResponse PreRoute(const httplib::Request& request,
                                            httplib::Response& response);
  // The upload's bytes: the body as sent (whatever its Content-Type), or from a multipart form
  // (a browser's) the field "photo" or else its first file. False with the response set when
  // there is none or it is over the limit.
  bool ReadUpload(const httplib::Request& request, const httplib::ContentReader& reader,
                  std::string* photo, httplib::Response& response);
  void HandleLocate(const httplib::Request& request, const std::string& body,
                    httplib::Response& response);
  // One line per request on stderr (time, client, method, path, status, bytes, ms) and the
  // figures /health reports.
  void LogRequest(const httplib::Request& request, const httplib::Response& response);
  void HandleAppliances(httplib::Response& response) const;
  void HandleHealth(httplib::Response& response) const;
  // The pages, and what the labelling page reads and writes.
  void AddPageRoutes();
  void AddLabelRoutes();
  // False with 403 (read-only) or 401 (no or a wrong token) set when `request` may not edit.
  bool MayEdit(const httplib::Request& request, httplib::Response& response);
  size_t MaxBodyBytes() const { return static_cast<size_t>(options.max_body_mb * 1024 * 1024); }
  std::string BodyTooLarge() const {
    std::ostringstream message;
    message << "request body larger than " << options.max_body_mb << " MiB";
    return message.str();
  }
  void RefuseCounted(httplib::Response& response, int status, const std::string& message) {
    ++refused;
    Refuse(response, status, message);
  }
};

void LocateServer::Impl::HandleLocate(const httplib::Request& request, const std::string& body,
                                      httplib::Response& response) {
  if (body.empty()) {
    return RefuseCounted(response, 400, "empty body: POST a JPEG or PNG photo as the request body");
  }
  const auto* bytes = reinterpret_cast<const uint8_t*>(body.data());
  identify::Photo photo;
  identify::LocateResult result;
  try {
    // The cheap refusals and the query's intrinsics first: a bad upload never waits for a slot.
    photo = identify::InspectPhoto(bytes, body.size(), options.max_megapixels);
    identify::IntrinsicsHint hint;
    hint.upright = IntrinsicsFromQuery(request, photo.width(), photo.height());
    // Decoding inside the slot bounds the decoded images in memory as well as the CPU.
    const Slots::Hold hold(*locate_slots);
    identify::DecodePixels(bytes, body.size(), &photo);
    result = locator->Locate(photo, hint);
    photo.upright.release();
  } catch (const identify::PhotoRejected& e) {
    return RefuseCounted(response, StatusFor(e.problem()), e.what());
  } catch (const InvalidArgument& e) {
    return RefuseCounted(response, 400, e.what());
  }
  ++located;
  nlohmann::json answer = identify::ToJson(result);
  answer["photo"] = {{"width", photo.width()},
                     {"height", photo.height()},
                     {"format", ToString(photo.stored.format)},
                     {"exif_orientation", photo.orientation.exif_code}};
  Reply(response, 200, answer);
}

httplib::Server::HandlerResponse LocateServer::Impl::PreRoute(const httplib::Request& request,
                                                              httplib::Response& response) {
  request_start = std::chrono::steady_clock::now();
  if (!request.has_header("Content-Length")) {
    // A POST (or PATCH) that says neither its length nor that it is chunked: cpp-httplib would wait
    // for the connection to close to find the body's end (the fuzzer found a multipart upload stall
    // so until the read timeout, then get no answer). Ask for the length instead.
    const bool chunked =
        request.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
    const bool has_body =
        request.method == "POST" || request.method == "PATCH" || request.method == "PUT";
    if (!has_body || chunked) return httplib::Server::HandlerResponse::Unhandled;
    response.set_header("Connection", "close");
    RefuseCounted(response, 411,
                  "a " + request.method + " needs a Content-Length (or chunked transfer encoding)");
    return httplib::Server::HandlerResponse::Handled;
  }
  // Lengths that disagree (how requests are smuggled past a proxy) make the body's end unknown:
  // refused at once, not read by one of them until the read timeout.
  const size_t lengths = request.get_header_value_count("Content-Length");
  for (size_t i = 1; i < lengths; ++i) {
    if (request.get_header_value("Content-Length", i) ==
        request.get_header_value("Content-Length")) {
      continue;
    }
    response.set_header("Connection", "close");
    RefuseCounted(response, 400, "the request has two different Content-Length headers");
    return httplib::Server::HandlerResponse::Handled;
  }
  const std::string declared = request.get_header_value("Content-Length");
  const std::optional<uint64_t> length = ParsePlainDecimal(declared);
  if (length && *length <= MaxBodyBytes()) return httplib::Server::HandlerResponse::Unhandled;
  // Answered before the body is read, and the connection closed: its bytes are never read.
  response.set_header("Connection", "close");
  if (!length) {
    RefuseCounted(response, 400, "malformed Content-Length: '" + declared + "'");
  } else {
    std::ostringstream message;
    message << "request body of " << *length << " bytes is larger than " << options.max_body_mb
            << " MiB: send the photo downscaled (a 1280x960 JPEG is plenty)";
    RefuseCounted(response, 413, message.str());
  }
  return httplib::Server::HandlerResponse::Handled;
}

bool LocateServer::Impl::ReadUpload(const httplib::Request& request,
                                    const httplib::ContentReader& reader, std::string* photo,
                                    httplib::Response& response) {
  const size_t max_bytes = MaxBodyBytes();
  bool too_large = false;
  size_t received = 0;
  const auto append = [&](std::string* to, const char* data, size_t length) {
    received += length;
    if (received > max_bytes) {
      too_large = true;
      return false;
    }
    to->append(data, length);
    return true;
  };
  bool complete = true;
  if (request.is_multipart_form_data()) {
    // The field "photo", or else the form's first file; other fields are skipped.
    std::string first_file;
    std::string* target = nullptr;
    bool first_seen = false;
    complete = reader(
        [&](const httplib::MultipartFormData& part) {
          target = nullptr;
          if (part.name == "photo") {
            photo->clear();
            target = photo;
          } else if (!part.filename.empty() && !first_seen) {
            first_seen = true;
            target = &first_file;
          }
          return true;
        },
        [&](const char* data, size_t length) {
          return target == nullptr || append(target, data, length);
        });
    if (photo->empty()) photo->swap(first_file);
    if (complete && photo->empty()) {
      RefuseCounted(response, 400,
                    "no photo in the form upload: send it as the file field 'photo' (or as the "
                    "request body, Content-Type: image/jpeg)");
      return false;
    }
  } else {
    complete = reader([&](const char* data, size_t length) { return append(photo, data, length); });
  }
  if (too_large) {
    RefuseCounted(response, 413, BodyTooLarge());
    return false;
  }
  if (!complete) {
    RefuseCounted(response, 400, "the upload was cut short: send the whole photo");
    return false;
  }
  return true;
}

void LocateServer::Impl::LogRequest(const httplib::Request& request,
                                    const httplib::Response& response) {
  double ms = -1.0;
  if (request_start) {
    ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - *request_start)
            .count();
    request_start.reset();
  }
  {
    const std::lock_guard<std::mutex> lock(requests_mutex);
    ++requests;
    if (response.status >= 400) ++errors;
    if (ms >= 0.0) {
      recent_ms.push_back(ms);
      if (recent_ms.size() > 1000) recent_ms.pop_front();
    }
  }
  if (!options.log_requests) return;
  std::ostringstream line;
  line << UtcNow() << ' ' << request.remote_addr << ' ' << request.method << ' ' << request.path
       << ' ' << response.status << ' ' << response.body.size() << " B ";
  if (ms >= 0.0) {
    line << std::lround(ms) << " ms\n";
  } else {
    line << "- ms\n";
  }
  std::cerr << line.str() << std::flush;
}

// What decides whether the labels changed: every label's name, type, point count and update time.
std::string LabelFingerprint(const std::vector<store::LabelRecord>& labels) {
  std::ostringstream fingerprint;
  for (const store::LabelRecord& label : labels) {
    fingerprint << label.name << '\n'
                << label.type << '\n'
                << label.points.size() << ' ' << label.updated_ns << '\n';
  }
  return fingerprint.str();
}

void LocateServer::Impl::WatchLabels() {
  std::string last = LabelFingerprint(locator->Labels());
  bool warned = false;
  std::unique_lock<std::mutex> lock(watch_mutex);
  const auto period = std::chrono::duration<double>(options.label_refresh_s);
  while (!watch_wakeup.wait_for(lock, period, [this] { return stop_requested.load(); })) {
    try {
      store::ModelOptions model_options;
      model_options.read_only = true;
      const store::Model model = store::Model::Open(model_path, model_options);
      const std::string now = LabelFingerprint(model.Labels());
      if (now != last) {
        locator->ReloadLabels(model);
        last = now;
        std::cerr << "serve: labels changed in " << model_path << ", now "
                  << locator->Labels().size() << "\n";
      }
      warned = false;
    } catch (const std::exception& e) {
      // A writer holding the file for a moment is normal; say so once, keep the labels we have.
      if (!warned) std::cerr << "serve: cannot re-read the labels (" << e.what() << ")\n";
      warned = true;
    }
  }
}

void LocateServer::Impl::HandleAppliances(httplib::Response& response) const {
  nlohmann::json appliances = nlohmann::json::array();
  for (const store::LabelRecord& label : locator->Labels()) {
    nlohmann::json points = nlohmann::json::array();
    for (const store::LabelPoint& point : label.points) {
      points.push_back({point.world.x(), point.world.y(), point.world.z()});
    }
    appliances.push_back({{"name", label.name}, {"type", label.type}, {"points", points}});
  }
  Reply(response, 200, {{"appliances", appliances}});
}

bool LocateServer::Impl::MayEdit(const httplib::Request& request, httplib::Response& response) {
  if (options.read_only) {
    RefuseCounted(response, 403, "this server is read-only (" + options.read_only_reason + ")");
    return false;
  }
  if (options.edit_token.empty()) return true;
  const std::string given = request.has_header("X-Sightmap-Token")
                                ? request.get_header_value("X-Sightmap-Token")
                                : request.get_param_value("token");
  if (SameSecret(given, options.edit_token)) return true;
  RefuseCounted(response, 401,
                given.empty() ? "editing needs the token 'sightmap serve' printed at start"
                              : "wrong edit token: use the one 'sightmap serve' printed at start");
  return false;
}

void LocateServer::Impl::AddPageRoutes() {
  auto page = [](const httplib::Request& request, httplib::Response& response) {
    const std::optional<WebAsset> asset = FindWebAsset(request.path);
    if (!asset) {
      Refuse(response, 404, "no such page " + request.path + ": the pages are / and /label");
      return;
    }
    response.set_content(asset->bytes.data(), asset->bytes.size(),
                         std::string(asset->content_type).c_str());
    // Embedded in this binary: a new build may change them, so browsers ask again each time.
    response.set_header("Cache-Control", "no-cache");
  };
  server.Get("/", page);
  server.Get("/index.html", page);
  server.Get("/label", page);
  server.Get("/label/", page);
  server.Get(R"(/static/[A-Za-z0-9_.-]+)", page);
}

void LocateServer::Impl::AddLabelRoutes() {
  LabelService& labels = *label_service;
  server.Get("/api/status", [this, &labels](const httplib::Request&, httplib::Response& response) {
    ReplyWith(response, refused, [&] {
      nlohmann::json status = labels.Status();
      status["token_required"] = !options.edit_token.empty();
      return status;
    });
  });
  server.Get("/api/keyframes",
             [this, &labels](const httplib::Request&, httplib::Response& response) {
               ReplyWith(response, refused, [&] { return labels.Keyframes(); });
             });
  server.Get(R"(/api/keyframes/(\d{1,15})/image\.jpg)",
             [this, &labels](const httplib::Request& request, httplib::Response& response) {
               int max_side = 0;
               if (request.has_param("max_side")) {
                 const std::string text = request.get_param_value("max_side");
                 const std::optional<uint64_t> value = ParsePlainDecimal(text);
                 if (!value || *value > 100000) {
                   RefuseCounted(response, 400,
                                 "max_side must be a number of pixels, got '" + text + "'");
                   return;
                 }
                 max_side = static_cast<int>(*value);
               }
               try {
                 const std::string jpeg = labels.KeyframeJpeg(PathId(request), max_side);
                 response.set_content(jpeg, "image/jpeg");
                 // A keyframe's image never changes once stored.
                 response.set_header("Cache-Control", "max-age=86400");
               } catch (const ServiceError& e) {
                 RefuseCounted(response, e.status(), e.what());
               } catch (const Error& e) {
                 RefuseCounted(response, 503, std::string(e.what()) + " (then try again)");
               }
             });
  server.Get(R"(/api/keyframes/(\d{1,15})/labels)",
             [this, &labels](const httplib::Request& request, httplib::Response& response) {
               ReplyWith(response, refused, [&] { return labels.KeyframeLabels(PathId(request)); });
             });
  server.Get("/api/labels", [this, &labels](const httplib::Request&, httplib::Response& response) {
    ReplyWith(response, refused, [&] { return labels.Labels(); });
  });
  server.Post("/api/labels",
              [this, &labels](const httplib::Request& request, httplib::Response& response) {
                if (!MayEdit(request, response)) return;
                ReplyWith(response, refused, [&] { return labels.AddPoint(ParseBody(request)); });
              });
  server.Patch(R"(/api/labels/(\d{1,15}))", [this, &labels](const httplib::Request& request,
                                                            httplib::Response& response) {
    if (!MayEdit(request, response)) return;
    ReplyWith(response, refused, [&] { return labels.Edit(PathId(request), ParseBody(request)); });
  });
  server.Delete(R"(/api/labels/(\d{1,15}))",
                [this, &labels](const httplib::Request& request, httplib::Response& response) {
                  if (!MayEdit(request, response)) return;
                  ReplyWith(response, refused, [&] { return labels.Remove(PathId(request)); });
                });
}

void LocateServer::Impl::HandleHealth(httplib::Response& response) const {
  const double uptime_s = SecondsSince(started);
  int64_t answered = 0;
  int64_t failed = 0;
  std::vector<double> times;
  {
    const std::lock_guard<std::mutex> lock(requests_mutex);
    answered = requests;
    failed = errors;
    times.assign(recent_ms.begin(), recent_ms.end());
  }
  Reply(response, 200,
        {{"status", "ok"},
         {"model", model_path},
         {"keyframes", locator->NumKeyframes()},
         {"labels", locator->Labels().size()},
         {"locate_threads", locate_threads},
         {"located", located.load()},
         {"refused", refused.load()},
         {"requests", answered},
         {"errors", failed},
         {"request_p50_ms", times.empty() ? 0.0 : Percentile(times, 0.5)},
         {"request_p95_ms", times.empty() ? 0.0 : Percentile(times, 0.95)},
         {"uptime_s", uptime_s}});
}

LocateServer::LocateServer(const std::string& model_path, const LocateServerOptions& options)
    : impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK_OPTIONS(options);
  Impl& impl = *impl_;
  impl.options = options;
  impl.model_path = model_path;
  impl.locate_threads = options.locate_threads > 0 ? options.locate_threads : HardwareThreads();
  impl.locate_slots = std::make_unique<Slots>(impl.locate_threads);
  const int connection_threads = options.connection_threads > 0
                                     ? options.connection_threads
                                     : std::max(32, 8 * impl.locate_threads);
  const size_t max_pending =
      static_cast<size_t>(connection_threads) + static_cast<size_t>(options.max_queued_connections);
  impl.server.new_task_queue = [connection_threads, max_pending] {
    return new BoundedTaskQueue(static_cast<size_t>(connection_threads), max_pending);
  };
  impl.server.set_payload_max_length(impl.MaxBodyBytes());
  impl.server.set_read_timeout(options.read_timeout_s, 0);
  impl.server.set_write_timeout(options.write_timeout_s, 0);
  impl.server.set_keep_alive_timeout(options.keep_alive_timeout_s);

  impl.server.set_socket_options(ReuseAddressOnly);
  httplib::Server& server = impl.server;
  server.set_pre_routing_handler(
      [&impl](const httplib::Request& request, httplib::Response& response) {
        return impl.PreRoute(request, response);
      });
  server.set_logger([&impl](const httplib::Request& request, const httplib::Response& response) {
    impl.LogRequest(request, response);
  });
  // With a content reader httplib leaves the body to the handler: a photo is taken whatever its
  // Content-Type (curl --data-binary says form-urlencoded, which httplib would cap at 8 KiB), and a
  // browser's multipart form too.
  server.Post("/locate", [&impl](const httplib::Request& request, httplib::Response& response,
                                 const httplib::ContentReader& reader) {
    std::string photo;
    if (impl.ReadUpload(request, reader, &photo, response)) {
      impl.HandleLocate(request, photo, response);
    }
  });
  server.Get("/appliances", [&impl](const httplib::Request&, httplib::Response& response) {
    impl.HandleAppliances(response);
  });
  server.Get("/health", [&impl](const httplib::Request&, httplib::Response& response) {
    impl.HandleHealth(response);
  });
  impl.AddPageRoutes();
  // httplib's own refusals (body over the limit, unknown path, wrong method) get a JSON body too.
  server.set_error_handler(httplib::Server::HandlerWithResponse(
      [&impl](const httplib::Request& request, httplib::Response& response) {
        if (!response.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        std::string message;
        if (response.status == 413) {
          message = impl.BodyTooLarge();
        } else if (response.status == 404) {
          message = "no such endpoint " + request.method + " " + request.path +
                    ": the pages are / (phones) and /label; the API is POST /locate, GET "
                    "/appliances, GET /health and /api/...";
        } else {
          message = "request refused (HTTP " + std::to_string(response.status) + ")";
        }
        ++impl.refused;
        Refuse(response, response.status, message);
        return httplib::Server::HandlerResponse::Handled;
      }));
  server.set_exception_handler(
      [](const httplib::Request&, httplib::Response& response, std::exception_ptr error) {
        std::string message = "internal error";
        try {
          std::rethrow_exception(error);
        } catch (const std::exception& e) {
          message = std::string("internal error: ") + e.what();
        } catch (...) {
        }
        Refuse(response, 500, message);
      });
}

LocateServer::~LocateServer() { Stop(); }

void LocateServer::Load(const identify::LoadProgress& progress) {
  Impl& impl = *impl_;
  SIGHTMAP_CHECK(impl.locator == nullptr, "LocateServer::Load called twice");
  {
    store::ModelOptions model_options;
    model_options.read_only = true;
    const store::Model model = store::Model::Open(impl.model_path, model_options);
    impl.locator = std::make_unique<identify::Locator>(model, impl.options.locator, progress);
    if (!impl.locator->LoadWarning().empty()) {
      std::cerr << "sightmap: " << impl.locator->LoadWarning() << "\n";
    }
  }
  LabelServiceOptions label_options = impl.options.labels;
  label_options.editable = !impl.options.read_only;
  label_options.read_only_reason = impl.options.read_only_reason;
  // An edit answers phones at once, not at the next label refresh.
  impl.label_service = std::make_unique<LabelService>(
      impl.model_path, label_options,
      [&impl](const store::Model& model) { impl.locator->ReloadLabels(model); });
  impl.AddLabelRoutes();  // they hold the label service
}

void LocateServer::Bind() {
  Impl& impl = *impl_;
  if (impl.options.port == 0) {
    impl.port = impl.server.bind_to_any_port(impl.options.host);
  } else {
    impl.port =
        impl.server.bind_to_port(impl.options.host, impl.options.port) ? impl.options.port : -1;
  }
  if (impl.port > 0) return;
  const int error = BindErrno(impl.options.host, impl.options.port);
  if (error == EADDRINUSE) {
    SIGHTMAP_THROW(Error, "port " << impl.options.port << " on " << impl.options.host
                                  << " is in use (another sightmap serve?): stop it, or pick "
                                     "another port (--port 0 takes a free one)");
  }
  SIGHTMAP_THROW(Error, "cannot listen on " << impl.options.host << ":" << impl.options.port << " ("
                                            << (error != 0 ? std::strerror(error) : "unknown error")
                                            << "): is it an address of this machine?");
}

int LocateServer::port() const { return impl_->port; }

void LocateServer::Run() {
  SIGHTMAP_CHECK(impl_->port > 0, "LocateServer::Run before Bind");
  SIGHTMAP_CHECK(impl_->locator != nullptr, "LocateServer::Run before Load");
  if (impl_->stop_requested) return;
  // The watcher is woken and joined however listening ends (Stop(), a failed accept, a throw).
  struct Watcher {
    Impl* impl;
    std::thread thread;
    ~Watcher() {
      impl->RequestStop();
      if (thread.joinable()) thread.join();
    }
  } watcher{impl_.get(), {}};
  if (impl_->options.label_refresh_s > 0.0) {
    watcher.thread = std::thread([this] { impl_->WatchLabels(); });
  }
  impl_->server.listen_after_bind();
}

void LocateServer::Stop() {
  impl_->RequestStop();
  impl_->server.stop();
}

size_t LocateServer::NumKeyframes() const { return impl_->locator->NumKeyframes(); }
size_t LocateServer::NumLabels() const { return impl_->locator->Labels().size(); }

// read_only_reason is not an option: the server says why it refuses edits.
SIGHTMAP_OPTIONS_JSON(LocateServerOptions, host, port, locate_threads, connection_threads,
                      max_queued_connections, max_body_mb, max_megapixels, read_timeout_s,
                      write_timeout_s, keep_alive_timeout_s, label_refresh_s, log_requests,
                      read_only, edit_token, locator, labels)

}  // namespace sightmap::cli
