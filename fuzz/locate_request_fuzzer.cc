// libFuzzer harness: POST /locate (and the labelling page's API) as `sightmap serve` handles it,
// end to end. A real LocateServer
// on 127.0.0.1 (a small synthetic model) gets one request per input over a real socket: the input
// chooses the query string, the Content-Type (none, image/jpeg, form-encoded, multipart with the
// body as its file or malformed multipart), the length (Content-Length true, absent, negative or
// huge, or chunked) and the body. Every request must get an answer, and no answer may be a 5xx: a
// 500 is an error the handler did not foresee.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include <fuzzer/FuzzedDataProvider.h>
#include <nlohmann/json.hpp>

#include "cli/locate_server.h"
#include "fuzz/fuzz_inputs.h"
#include "store/model.h"
#include "store/synthetic_model.h"

namespace {

int g_port = 0;

// A model of four 320x240 synthetic keyframes: enough for a Locator (it trains a vocabulary on
// them), small enough to load in a moment.
std::string MakeModel() {
  const std::string path = sightmap::fuzz::ScratchDir() + "/model.db";
  sightmap::store::Model model = sightmap::store::Model::Open(path);
  sightmap::store::SyntheticKeyframeOptions options;
  options.width = 320;
  options.height = 240;
  options.num_features = 200;
  const sightmap::SessionId session = model.BeginSession({});
  for (int i = 0; i < 4; ++i)
    model.AddKeyframe(sightmap::store::MakeSyntheticKeyframe(session, i, options));
  model.EndSession(session, sightmap::store::SessionEnd::kFinished, 1);
  return path;
}

// Bytes a URL query may carry as they are; the rest percent-encoded, so the request line holds.
std::string QueryText(const std::string& raw) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string query;
  for (const char c : raw) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) || c == '=' || c == '&' || c == '.' || c == '-' || c == '_') {
      query.push_back(c);
    } else {
      query += std::string("%") + kHex[byte >> 4] + kHex[byte & 15];
    }
  }
  return query;
}

std::string BuildRequest(FuzzedDataProvider& in) {
  const std::string query = QueryText(in.ConsumeRandomLengthString(48));
  const int content_type = in.ConsumeIntegralInRange(0, 4);
  const int length_mode = in.ConsumeIntegralInRange(0, 4);
  // The labelling page's endpoints share the server's request handling; 0 is POST /locate.
  static const char* kRoutes[] = {"POST /locate",
                                  "POST /api/labels",
                                  "PATCH /api/labels/1",
                                  "DELETE /api/labels/1",
                                  "GET /api/keyframes/1/image.jpg",
                                  "GET /api/keyframes/2/labels"};
  const int route = in.ConsumeIntegralInRange(0, 5);
  std::string body = in.ConsumeRemainingBytesAsString();
  static const char* kTypes[] = {nullptr, "image/jpeg", "application/x-www-form-urlencoded",
                                 "multipart/form-data; boundary=sightmapfuzz",
                                 "multipart/form-data; boundary=sightmapfuzz"};
  if (content_type == 3) {
    body =
        "--sightmapfuzz\r\nContent-Disposition: form-data; name=\"photo\"; "
        "filename=\"q.jpg\"\r\nContent-Type: image/jpeg\r\n\r\n" +
        body + "\r\n--sightmapfuzz--\r\n";
  }
  std::string request =
      std::string(kRoutes[route]) + (query.empty() ? "" : "?" + query) + " HTTP/1.1\r\n";
  request += "Host: 127.0.0.1\r\nConnection: close\r\n";
  if (kTypes[content_type])
    request += std::string("Content-Type: ") + kTypes[content_type] + "\r\n";
  // Where the server answers before reading a body (no length, a malformed or huge one) none is
  // sent: closing a socket with unread bytes sends a reset, which can destroy the answer in the
  // client's buffer before it is read, and the harness would report a missing answer.
  switch (length_mode) {
    case 0:
      request += "Content-Length: " + std::to_string(body.size()) + "\r\n";
      break;
    case 1:
      body.clear();  // no length at all: 411
      break;
    case 2:
      request += "Content-Length: -5\r\n";
      body.clear();
      break;
    case 3:
      request += "Content-Length: 99999999999\r\n";
      body.clear();
      break;
    default: {
      // Chunked: the body as one chunk and the last chunk.
      request += "Transfer-Encoding: chunked\r\n";
      char size[32];
      std::snprintf(size, sizeof(size), "%zx\r\n", body.size());
      body = (body.empty() ? std::string() : size + body + "\r\n") + "0\r\n\r\n";
      break;
    }
  }
  return request + "\r\n" + body;
}

// Sends the request and reads the answer to its end (Connection: close); "" when none came.
std::string Exchange(const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) std::abort();
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(g_port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) std::abort();
  size_t sent = 0;
  while (sent < request.size()) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may answer (413) and close before the body is sent
    sent += static_cast<size_t>(n);
  }
  // No half-close: cpp-httplib takes a client that shut its sending side for gone, and drops the
  // answer. Every request built here is complete, so the server never waits for more.
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof(buffer), 0)) > 0;) {
    answer.append(buffer, static_cast<size_t>(n));
  }
  ::close(fd);
  return answer;
}

// A label an input created is removed again: labels piling up over a run would slow every later
// input (each edit reloads them all into the Locator) without finding anything new.
void RemoveCreatedLabel(const std::string& request, const std::string& answer) {
  if (request.rfind("POST /api/labels", 0) != 0 || answer.rfind("HTTP/1.1 200", 0) != 0) return;
  const size_t body = answer.find("\r\n\r\n");
  if (body == std::string::npos) return;
  const nlohmann::json created =
      nlohmann::json::parse(answer.substr(body + 4), nullptr, /*allow_exceptions=*/false);
  if (!created.is_object() || !created.contains("label")) return;
  const int64_t id = created["label"].value("id", int64_t{0});
  Exchange("DELETE /api/labels/" + std::to_string(id) +
           " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  sightmap::cli::LocateServerOptions options;
  options.port = 0;
  options.log_requests = false;
  options.read_timeout_s = 5;
  options.locate_threads = 1;
  options.max_megapixels = 2.0;
  options.max_body_mb = 4.0;
  options.label_refresh_s = 0.0;
  // Never destroyed: it serves until the fuzzer exits.
  auto* server = new sightmap::cli::LocateServer(MakeModel(), options);
  server->Bind();
  server->Load();
  g_port = server->port();
  std::thread([server] { server->Run(); }).detach();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  const std::string request = BuildRequest(in);
  std::string answer = Exchange(request);
  if (answer.empty()) {
    // cpp-httplib closes without draining what it did not read (a multipart epilogue, say), so
    // the kernel's reset can destroy an answer already sent: about 1 in 1,500 inputs. Only a
    // request that gets no answer twice is a finding.
    std::fprintf(stderr, "no answer; asking again\n");
    answer = Exchange(request);
  }
  if (answer.rfind("HTTP/1.1 ", 0) != 0) {
    std::fprintf(stderr, "no HTTP answer (got %zu bytes)\n", answer.size());
    std::abort();
  }
  if (answer[9] == '5') {
    std::fprintf(stderr, "server error:\n%s\n", answer.c_str());
    std::abort();
  }
  RemoveCreatedLabel(request, answer);
  return 0;
}
