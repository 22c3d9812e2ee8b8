// `sightmap serve` end to end: the real binary on 127.0.0.1 (--port 0), a real model built from
// the simulator's walk, real session-2 phone photos, and cpp-httplib clients. Covers the health
// and appliance endpoints, photos located by 4 clients at once, every kind of bad upload (the
// server must answer 4xx and keep serving), and a clean stop on SIGTERM.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera.h"
#include "core/timing.h"
#include "identify/exif_testing.h"
#include "identify/identify_eval.h"
#include "identify/sim_model_testing.h"
#include "slam/matching.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

// Last: httplib.h pulls in <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace sightmap {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// `sightmap serve ARGS` as a child process; reads its stdout until it prints the URL. SIGTERM and
// reaping in the destructor, so a failed assertion never leaves a server behind.
class ServerProcess {
 public:
  explicit ServerProcess(const std::vector<std::string>& args) {
    int out[2];
    if (::pipe(out) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], 1);
      ::close(out[0]);
      ::close(out[1]);
      std::vector<std::string> all = {SIGHTMAP_BINARY, "serve"};
      all.insert(all.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (std::string& arg : all) argv.push_back(arg.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    ::close(out[1]);
    out_ = out[0];
    // The model loads in seconds; the URL line follows.
    const std::regex url(R"(listening on http://[0-9.]+:([0-9]+))");
    const Clock::time_point deadline = Clock::now() + std::chrono::seconds(120);
    while (Clock::now() < deadline && port_ == 0) {
      pollfd fd{out_, POLLIN, 0};
      if (::poll(&fd, 1, 200) <= 0) continue;
      char buffer[512];
      const ssize_t n = ::read(out_, buffer, sizeof(buffer));
      if (n <= 0) break;  // exited
      output_.append(buffer, static_cast<size_t>(n));
      std::smatch match;
      if (std::regex_search(output_, match, url)) port_ = std::stoi(match[1]);
    }
  }
  ~ServerProcess() {
    if (pid_ > 0 && exit_code_ < 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    if (out_ >= 0) ::close(out_);
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  const std::string& output() const { return output_; }

  // Sends `signal_number` and waits up to `timeout` for the exit; returns its code (-1: still up).
  int StopWith(int signal_number, std::chrono::seconds timeout) {
    ::kill(pid_, signal_number);
    const Clock::time_point deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        char buffer[512];
        ssize_t n = 0;
        while ((n = ::read(out_, buffer, sizeof(buffer))) > 0) {
          output_.append(buffer, static_cast<size_t>(n));
        }
        return exit_code_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int port_ = 0;
  int exit_code_ = -1;
  std::string output_;
};

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string Encode(const std::string& extension, const cv::Mat& image) {
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes));
  return std::string(bytes.begin(), bytes.end());
}

nlohmann::json Json(const httplib::Result& result) {
  if (!result) return nlohmann::json();
  return nlohmann::json::parse(result->body, nullptr, /*allow_exceptions=*/false);
}

// One model and one set of session-2 photos for the suite; one server for the suite.
class ServeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // A server that refuses a body before reading it closes the connection under a client that is
    // still sending: the write fails with EPIPE, which must not kill the test.
    ::signal(SIGPIPE, SIG_IGN);
    dir_ = new fs::path(testing::MakeTempDir("serve-test"));
    identify::SimModelOptions options;
    options.keyframes = 60;
    identify::BuildSimulatorModel((*dir_ / "model.db").string(), options);
    // Phone photos of another day (session 2), with ground truth, as a phone would send them.
    const testing::CommandResult generated = testing::RunCommand(
        SIGHTMAP_BINARY,
        "sim generate --scene office --trajectory handheld --session 2 --seed 7 "
        "--frames 1 --queries 12 --out " +
            (*dir_ / "queries").string() + " 2>&1");
    ASSERT_EQ(generated.exit_code, 0) << generated.out;
    server_ = new ServerProcess({"--model", (*dir_ / "model.db").string(), "--port", "0",
                                 "--threads", "2", "--max-body-mb", "2"});
  }
  static void TearDownTestSuite() {
    delete server_;
    std::error_code ignored;
    fs::remove_all(*dir_, ignored);
    delete dir_;
  }

  static std::vector<std::string> Photos() {
    std::vector<std::string> photos;
    for (const auto& entry : fs::directory_iterator(*dir_ / "queries" / "queries")) {
      if (entry.path().extension() == ".jpg") photos.push_back(ReadBytes(entry.path()));
    }
    return photos;
  }

  static httplib::Client Client() {
    httplib::Client client("127.0.0.1", server_->port());
    client.set_read_timeout(60, 0);
    client.set_write_timeout(60, 0);
    return client;
  }

  void ExpectStillServing() {
    const httplib::Result health = Client().Get("/health");
    ASSERT_TRUE(health) << "server gone: " << httplib::to_string(health.error());
    EXPECT_EQ(health->status, 200);
  }

  static fs::path* dir_;
  static ServerProcess* server_;
};

fs::path* ServeTest::dir_ = nullptr;
ServerProcess* ServeTest::server_ = nullptr;

TEST_F(ServeTest, HealthAndAppliances) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const httplib::Result health = Client().Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(health->get_header_value("Content-Type"), "application/json");
  const nlohmann::json h = Json(health);
  EXPECT_EQ(h["status"], "ok");
  EXPECT_EQ(h["keyframes"], 60);
  EXPECT_GT(h["labels"].get<int>(), 5);

  const nlohmann::json a = Json(Client().Get("/appliances"));
  ASSERT_TRUE(a.contains("appliances")) << a.dump();
  EXPECT_EQ(a["appliances"].size(), h["labels"].get<size_t>());
  for (const nlohmann::json& appliance : a["appliances"]) {
    EXPECT_FALSE(appliance["name"].get<std::string>().empty());
    ASSERT_FALSE(appliance["points"].empty());
    EXPECT_EQ(appliance["points"][0].size(), 3u);
  }
}

TEST_F(ServeTest, ALabelAddedWhileServingIsServedWithoutARestart) {
  const std::string model = (*dir_ / "model.db").string();
  const size_t before = Json(Client().Get("/appliances"))["appliances"].size();
  const testing::CommandResult added = testing::RunCommand(
      SIGHTMAP_BINARY, "label add --model " + model + " --name zz_added_while_serving " +
                           "--type lamp --point 1,2,1.5 2>&1");
  ASSERT_EQ(added.exit_code, 0) << added.out;
  // The server re-reads the labels every 2 s: wait for it, but not for ever.
  bool seen = false;
  for (int attempt = 0; attempt < 50 && !seen; ++attempt) {
    const nlohmann::json a = Json(Client().Get("/appliances"));
    seen = a["appliances"].size() == before + 1;
    if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_TRUE(seen) << "the new label was not served within 10 s";
  const testing::CommandResult removed = testing::RunCommand(
      SIGHTMAP_BINARY, "label remove --model " + model + " --name zz_added_while_serving 2>&1");
  ASSERT_EQ(removed.exit_code, 0) << removed.out;
  bool gone = false;
  for (int attempt = 0; attempt < 50 && !gone; ++attempt) {
    gone = Json(Client().Get("/appliances"))["appliances"].size() == before;
    if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_TRUE(gone) << "the removed label was still served after 10 s";
}

TEST_F(ServeTest, FourClientsLocateRealPhotosAtOnce) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const std::vector<std::string> photos = Photos();
  ASSERT_GE(photos.size(), 8u);
  std::atomic<int> answered{0};
  std::atomic<int> matched{0};
  std::vector<std::string> failures(4);
  std::vector<std::thread> clients;
  for (size_t c = 0; c < 4; ++c) {
    clients.emplace_back([&, c] {
      httplib::Client client = Client();
      for (size_t i = c; i < photos.size(); i += 4) {
        const httplib::Result result = client.Post("/locate", photos[i], "image/jpeg");
        if (!result || result->status != 200) {
          failures[c] += "photo " + std::to_string(i) + ": " +
                         (result ? std::to_string(result->status) + " " + result->body
                                 : httplib::to_string(result.error())) +
                         "\n";
          continue;
        }
        const nlohmann::json answer = Json(result);
        if (!answer.contains("matched") || !answer.contains("timings_ms") ||
            answer["photo"]["width"] != 1280) {
          failures[c] += "photo " + std::to_string(i) + ": unexpected answer " + answer.dump();
          continue;
        }
        ++answered;
        matched += answer["matched"].get<bool>() ? 1 : 0;
      }
    });
  }
  for (std::thread& client : clients) client.join();
  for (const std::string& failure : failures) EXPECT_TRUE(failure.empty()) << failure;
  EXPECT_EQ(answered, static_cast<int>(photos.size()));
  // Matching quality is the Locator's test; here some photos must come back located.
  EXPECT_GT(matched, 0);
}

TEST_F(ServeTest, GivenIntrinsicsAndPngAreAccepted) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const cv::Mat photo = cv::imread((*dir_ / "queries" / "queries" / "0000.jpg").string());
  ASSERT_FALSE(photo.empty());
  const httplib::Result result = Client().Post("/locate?fx=1000&fy=1000&cx=639.5&cy=479.5",
                                               Encode(".png", photo), "image/png");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200) << result->body;
  const nlohmann::json answer = Json(result);
  EXPECT_EQ(answer["photo"]["format"], "png");
  EXPECT_EQ(answer["intrinsics"]["source"], "given");
  EXPECT_DOUBLE_EQ(answer["intrinsics"]["fx"].get<double>(), 1000.0);
}

// A phone's JPEG carries its focal length in EXIF: the server builds the intrinsics from it.
TEST_F(ServeTest, ExifFocalLengthGivesTheIntrinsics) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  std::string jpeg = Photos().at(0);
  // APP1 "Exif": little-endian TIFF, IFD0 -> Exif IFD holding FocalLengthIn35mmFilm = 26 mm.
  const uint8_t app1[] = {0xFF, 0xE1, 0x00, 0x34, 'E', 'x', 'i', 'f', 0,
                          0,  // marker, length 52, identifier
                          'I', 'I', 0x2A, 0x00, 0x08, 0x00, 0x00, 0x00,  // TIFF header, IFD0 at 8
                          0x01, 0x00, 0x69, 0x87, 0x04, 0x00, 0x01, 0x00, 0x00, 0x00, 0x1A, 0x00,
                          0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // IFD0: ExifIFDPointer (LONG) = 26;
                                                               // no next IFD
                          0x01, 0x00, 0x05, 0xA4, 0x03, 0x00, 0x01, 0x00, 0x00, 0x00, 0x1A, 0x00,
                          0x00, 0x00, 0x00, 0x00, 0x00, 0x00};  // Exif IFD: FocalLengthIn35mmFilm
                                                                // (SHORT) = 26; no next IFD
  jpeg.insert(2, reinterpret_cast<const char*>(app1), sizeof(app1));
  const httplib::Result result = Client().Post("/locate", jpeg, "image/jpeg");
  ASSERT_TRUE(result);
  ASSERT_EQ(result->status, 200) << result->body;
  const nlohmann::json answer = Json(result);
  EXPECT_EQ(answer["intrinsics"]["source"], "exif") << result->body;
  // 26 mm on the 35 mm diagonal (43.27 mm) over the photo's 1600 px diagonal.
  EXPECT_NEAR(answer["intrinsics"]["fx"].get<double>(), 26.0 * 1600.0 / std::hypot(36.0, 24.0),
              0.5);
}

// A phone held upright writes its pixels sideways and EXIF orientation 6. The server turns the
// pixels and the EXIF camera together: square pixels on the upright photo, and the pose of the
// photo sent upright.
TEST_F(ServeTest, ASidewaysStoredPortraitPhotoIsLocatedUpright) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const auto post = [&](const std::vector<uint8_t>& jpeg) {
    const httplib::Result result =
        Client().Post("/locate", std::string(jpeg.begin(), jpeg.end()), "image/jpeg");
    EXPECT_TRUE(result);
    EXPECT_EQ(result ? result->status : 0, 200) << (result ? result->body : "no answer");
    return result ? Json(result) : nlohmann::json();
  };
  const auto position = [](const nlohmann::json& json) {
    const auto p = json["pose"]["world_from_cam"]["position"];
    return Eigen::Vector3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
  };
  testing::ExifFields fields;
  fields.focal_35mm = 26;
  int compared = 0;
  for (const std::string& plain : Photos()) {
    const cv::Mat upright =
        cv::imdecode(std::vector<uint8_t>(plain.begin(), plain.end()), cv::IMREAD_COLOR);
    fields.orientation = 1;
    const nlohmann::json expected = post(testing::JpegWithExif(upright, fields));
    if (!expected.value("matched", false)) continue;

    cv::Mat sideways;
    cv::rotate(upright, sideways, cv::ROTATE_90_COUNTERCLOCKWISE);
    fields.orientation = 6;
    const nlohmann::json answer = post(testing::JpegWithExif(sideways, fields));
    EXPECT_EQ(answer["photo"]["width"], 1280) << answer;
    EXPECT_EQ(answer["photo"]["height"], 960) << answer;
    EXPECT_EQ(answer["photo"]["exif_orientation"], 6) << answer;
    EXPECT_EQ(answer["intrinsics"]["source"], "exif");
    EXPECT_EQ(answer["intrinsics"]["width"], 1280);
    EXPECT_DOUBLE_EQ(answer["intrinsics"]["fx"].get<double>(),
                     expected["intrinsics"]["fx"].get<double>());
    EXPECT_DOUBLE_EQ(answer["intrinsics"]["fy"].get<double>(),
                     expected["intrinsics"]["fy"].get<double>());
    ASSERT_TRUE(answer.value("matched", false)) << answer;
    // Re-encoding moves a few features: centimetres, not the metres of a stretched camera.
    EXPECT_LT((position(answer) - position(expected)).norm(), 0.05) << answer;
    if (++compared == 2) break;
  }
  EXPECT_EQ(compared, 2) << "too few photos matched at the EXIF focal length";
}

TEST_F(ServeTest, BadUploadsGet4xxAndTheServerKeepsServing) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const std::string jpeg = Photos().at(0);
  const std::string png =
      Encode(".png", cv::imread((*dir_ / "queries" / "queries" / "0000.jpg").string()));
  // A real 100-megapixel image (10000 x 10000 grey, ~100 KB as PNG): refused from its header.
  const std::string huge_png = Encode(".png", cv::Mat(10000, 10000, CV_8UC1, cv::Scalar(90)));
  // A JPEG whose frame header claims 10000 x 10000.
  std::string huge_jpeg = Encode(".jpg", cv::Mat(16, 16, CV_8UC3, cv::Scalar(1, 2, 3)));
  for (size_t i = 2; i + 9 < huge_jpeg.size(); ++i) {
    if (static_cast<uint8_t>(huge_jpeg[i]) == 0xFF &&
        static_cast<uint8_t>(huge_jpeg[i + 1]) == 0xC0) {
      huge_jpeg[i + 5] = 0x27;
      huge_jpeg[i + 6] = 0x10;
      huge_jpeg[i + 7] = 0x27;
      huge_jpeg[i + 8] = 0x10;
      break;
    }
  }
  const std::string cut_jpeg = jpeg.substr(0, jpeg.size() * 6 / 10) + "\xFF\xD9";
  struct Case {
    const char* what;
    std::string path;
    std::string body;
    int status;
  };
  const std::vector<Case> cases = {
      {"empty body", "/locate", "", 400},
      {"text", "/locate", "{\"photo\": \"not really\"}", 415},
      {"truncated png", "/locate", png.substr(0, png.size() / 3), 400},
      // libjpeg decodes a cut JPEG, grey where the bytes ran out: refused, not matched.
      {"truncated jpeg", "/locate", jpeg.substr(0, jpeg.size() / 3), 400},
      // A cut JPEG given an end marker passes the end-marker check; libjpeg only warns (to
      // stderr) and fills the missing rows with grey: refused with its reason, not matched.
      {"cut jpeg with an end marker", "/locate", cut_jpeg, 400},
      // Too small to hold a feature (OpenCV's feature pyramid threw on a 1-px side: 500).
      {"1x1 png", "/locate", Encode(".png", cv::Mat(1, 1, CV_8UC3, cv::Scalar(9, 9, 9))), 400},
      {"1x1000 jpeg", "/locate", Encode(".jpg", cv::Mat(1000, 1, CV_8UC3, cv::Scalar(9))), 400},
      {"1000x1 png", "/locate", Encode(".png", cv::Mat(1, 1000, CV_8UC1, cv::Scalar(9))), 400},
      {"100 MP png", "/locate", huge_png, 413},
      {"100 MP jpeg header", "/locate", huge_jpeg, 413},
      {"three of four intrinsics", "/locate?fx=1000&fy=1000&cx=640", jpeg, 400},
      {"intrinsics not numbers", "/locate?fx=a&fy=1000&cx=640&cy=480", jpeg, 400},
      // Quoted in the answer: bytes that are not UTF-8 must not turn the 400 into a 500.
      {"intrinsics not UTF-8", "/locate?fx=3%FF%FF&fy=1000&cx=640&cy=480", jpeg, 400},
      {"a label edit that is not JSON", "/api/labels", jpeg, 400},
      {"a label edit without a pixel", "/api/labels", "{\"name\": \"lamp\", \"keyframe\": 1}", 400},
      {"unknown endpoint", "/nothing", jpeg, 404},
  };
  for (const Case& c : cases) {
    const httplib::Result result = Client().Post(c.path, c.body, "application/octet-stream");
    ASSERT_TRUE(result) << c.what << ": " << httplib::to_string(result.error());
    EXPECT_EQ(result->status, c.status) << c.what << ": " << result->body;
    const nlohmann::json answer = Json(result);
    EXPECT_TRUE(answer.contains("error")) << c.what << ": " << result->body;
    EXPECT_EQ(answer["status"], c.status) << c.what;
    if (c.body == cut_jpeg) {
      EXPECT_NE(answer["error"].get<std::string>().find("premature end of data"), std::string::npos)
          << answer;
    }
    ExpectStillServing();
  }
  // A body over the limit is refused from its declared length, before it is read, and the
  // connection closed: a client still sending it may see the 413 or only the closed connection.
  const httplib::Result over = Client().Post("/locate", std::string(3 << 20, 'x'), "image/jpeg");
  if (over) {
    EXPECT_EQ(over->status, 413) << over->body;
  }
  ExpectStillServing();
  const nlohmann::json health = Json(Client().Get("/health"));
  EXPECT_GE(health["refused"].get<int>(), static_cast<int>(cases.size()));
}

// What a user's tools send: curl --data-binary says form-urlencoded, a browser's form (curl -F)
// sends multipart; both carry the photo and get the same answer as a plain image body.
TEST_F(ServeTest, FormAndMultipartUploadsAreLocatedLikeAPlainBody) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const std::string jpeg = Photos().at(1);
  const httplib::Result plain = Client().Post("/locate", jpeg, "image/jpeg");
  ASSERT_TRUE(plain);
  ASSERT_EQ(plain->status, 200) << plain->body;
  const nlohmann::json expected = Json(plain)["matched"];
  const httplib::Result form = Client().Post("/locate", jpeg, "application/x-www-form-urlencoded");
  ASSERT_TRUE(form);
  EXPECT_EQ(form->status, 200) << form->body;
  EXPECT_EQ(Json(form)["matched"], expected);
  const httplib::MultipartFormDataItems items = {{"note", "kitchen", "", ""},
                                                 {"photo", jpeg, "q.jpg", "image/jpeg"}};
  const httplib::Result multipart = Client().Post("/locate", items);
  ASSERT_TRUE(multipart);
  EXPECT_EQ(multipart->status, 200) << multipart->body;
  EXPECT_EQ(Json(multipart)["matched"], expected);
  EXPECT_EQ(Json(multipart)["photo"]["width"], Json(plain)["photo"]["width"]);
  const httplib::MultipartFormDataItems no_file = {{"note", "kitchen", "", ""}};
  const httplib::Result nothing = Client().Post("/locate", no_file);
  ASSERT_TRUE(nothing);
  EXPECT_EQ(nothing->status, 400);
  EXPECT_NE(nothing->body.find("field 'photo'"), std::string::npos) << nothing->body;
}

// The status line of what the server answers to `request` sent as raw bytes, within `timeout`
// ("" when it did not answer in time).
// With until_closed, reads on until the server closes the connection (after its request log,
// which counts the request), for a request that asks for `Connection: close`.
std::string RawStatusLine(int port, const std::string& request, std::chrono::seconds timeout,
                          bool until_closed = false) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string answer;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) ==
          static_cast<ssize_t>(request.size())) {
    const Clock::time_point deadline = Clock::now() + timeout;
    while ((until_closed || answer.find("\r\n") == std::string::npos) && Clock::now() < deadline) {
      pollfd ready{fd, POLLIN, 0};
      if (::poll(&ready, 1, 50) <= 0) continue;
      char buffer[256];
      const ssize_t n = ::recv(fd, buffer, sizeof(buffer), 0);
      if (n <= 0) break;
      answer.append(buffer, static_cast<size_t>(n));
    }
  }
  ::close(fd);
  return answer.substr(0, answer.find("\r\n"));
}

// A declared length is judged before any body byte arrives: over the limit 413, malformed 400,
// at once (the server would otherwise wait for the body until its read timeout).
TEST_F(ServeTest, ADeclaredLengthIsRefusedBeforeTheBody) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const auto status_for = [](const std::string& length) {
    return RawStatusLine(server_->port(),
                         "POST /locate HTTP/1.1\r\nHost: x\r\nContent-Type: image/jpeg\r\n"
                         "Content-Length: " +
                             length + "\r\n\r\n",
                         std::chrono::seconds(2));
  };
  EXPECT_EQ(status_for("99999999999"), "HTTP/1.1 413 Payload Too Large");
  EXPECT_EQ(status_for("-5"), "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(status_for("12abc"), "HTTP/1.1 400 Bad Request");
  // Two lengths that disagree: refused at once (it waited for the 5 s read timeout).
  const Clock::time_point sent = Clock::now();
  EXPECT_EQ(status_for("5\r\nContent-Length: 7"), "HTTP/1.1 400 Bad Request");
  EXPECT_LT(Clock::now() - sent, std::chrono::seconds(1));
  // Found by locate_request_fuzzer: a multipart upload with no length at all stalled until the
  // read timeout and got no answer. It is asked for its length at once.
  EXPECT_EQ(RawStatusLine(server_->port(),
                          "POST /locate HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; "
                          "boundary=b\r\n\r\n--b\r\nContent-Disposition: form-data; "
                          "name=\"photo\"; filename=\"q.jpg\"\r\n\r\nxyz\r\n--b--\r\n",
                          std::chrono::seconds(2)),
            "HTTP/1.1 411 Length Required");
  // The same for a label edit (PATCH), which waited for the read timeout before.
  EXPECT_EQ(RawStatusLine(server_->port(),
                          "PATCH /api/labels/1 HTTP/1.1\r\nHost: x\r\n\r\n{\"type\": \"lamp\"}",
                          std::chrono::seconds(2)),
            "HTTP/1.1 411 Length Required");
  ExpectStillServing();
}

// Clients that send half their headers and then nothing (16 of them, twice the old pool) do not
// keep /health from answering, and each request is counted with its time.
// The server's resident memory [MiB] from /proc (0 when it cannot be read).
double ResidentMiB(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;  // kB
  }
  return 0.0;
}

// Load: 1,000 requests from 8 clients at once, good photos among the bad uploads. Every answer
// has the status its request calls for, none fails, and the server's memory after the run is
// within 10% of what it held after the first 100 (no leak per request).
TEST_F(ServeTest, AThousandMixedRequestsFromEightClients) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  // The first four photos of queries.json, phone-sized at 640x480: the load is on the server's
  // handling, not on feature counts. Plain uploads carry their true intrinsics (one focal length
  // to try, not four); multipart ones have theirs estimated.
  const std::vector<identify::QueryTruth> truths =
      identify::ReadQueryTruths((*dir_ / "queries").string());
  ASSERT_GE(truths.size(), 4u);
  std::vector<std::string> small;
  std::vector<std::string> intrinsics;  // as /locate's query string
  for (size_t i = 0; i < 4; ++i) {
    ASSERT_TRUE(truths[i].intrinsics.has_value()) << truths[i].image_path;
    const Intrinsics k = truths[i].intrinsics->Scaled(640, 480);
    intrinsics.push_back("?fx=" + std::to_string(k.fx) + "&fy=" + std::to_string(k.fy) +
                         "&cx=" + std::to_string(k.cx) + "&cy=" + std::to_string(k.cy));
    const std::string photo = ReadBytes(truths[i].image_path);
    const std::vector<uint8_t> bytes(photo.begin(), photo.end());
    cv::Mat image;
    cv::resize(cv::imdecode(bytes, cv::IMREAD_COLOR), image, cv::Size(640, 480), 0, 0,
               cv::INTER_AREA);
    small.push_back(Encode(".jpg", image));
  }
  std::string huge_jpeg = Encode(".jpg", cv::Mat(16, 16, CV_8UC3, cv::Scalar(1, 2, 3)));
  for (size_t i = 2; i + 9 < huge_jpeg.size(); ++i) {
    if (static_cast<uint8_t>(huge_jpeg[i]) == 0xFF &&
        static_cast<uint8_t>(huge_jpeg[i + 1]) == 0xC0) {
      huge_jpeg[i + 5] = huge_jpeg[i + 7] = 0x27;  // 10000 x 10000
      huge_jpeg[i + 6] = huge_jpeg[i + 8] = 0x10;
      break;
    }
  }
  struct Kind {
    const char* what;
    std::string path;
    int status;
  };
  const std::vector<Kind> kinds = {
      {"photo", "/locate", 200},
      {"multipart photo", "/locate", 200},
      {"empty body", "/locate", 400},
      {"text", "/locate", 415},
      {"truncated jpeg", "/locate", 400},
      {"100 MP jpeg header", "/locate", 413},
      {"three of four intrinsics", "/locate?fx=500&fy=500&cx=320", 400},
      {"health", "/health", 200},
      {"unknown endpoint", "/nothing", 404},
      {"appliances", "/appliances", 200},
  };
  constexpr int kRequests = 1000;
  constexpr int kClients = 8;
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::atomic<int> failed{0};
  std::atomic<int> wrong_status{0};
  std::atomic<double> rss_after_100{0.0};
  std::mutex times_mutex;
  std::vector<std::vector<double>> times_ms(kinds.size());
  std::string first_problem;
  const auto send = [&](httplib::Client& client, int index) -> httplib::Result {
    const size_t kind = static_cast<size_t>(index) % kinds.size();
    const size_t which = static_cast<size_t>(index / 10) % small.size();
    const std::string& photo = small[which];
    const std::string& path = kinds[kind].path;
    switch (kind) {
      case 0:
        return client.Post(path + intrinsics[which], photo, "image/jpeg");
      case 1:
        return client.Post(
            path, httplib::MultipartFormDataItems{{"photo", photo, "q.jpg", "image/jpeg"}});
      case 2:
        return client.Post(path, "", "image/jpeg");
      case 3:
        return client.Post(path, "{\"photo\": \"not really\"}", "application/json");
      case 4:
        return client.Post(path, photo.substr(0, photo.size() / 3), "image/jpeg");
      case 5:
        return client.Post(path, huge_jpeg, "image/jpeg");
      case 6:
        return client.Post(path, photo, "image/jpeg");
      case 8:
        return client.Post(path, photo, "image/jpeg");
      default:
        return client.Get(path);
    }
  };
  const Clock::time_point start = Clock::now();
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&] {
      httplib::Client client = Client();
      for (int index; (index = next++) < kRequests;) {
        const Clock::time_point sent = Clock::now();
        const httplib::Result result = send(client, index);
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - sent).count();
        const size_t kind = static_cast<size_t>(index) % kinds.size();
        std::lock_guard<std::mutex> lock(times_mutex);
        times_ms[kind].push_back(ms);
        if (!result) {
          ++failed;
          if (first_problem.empty()) {
            first_problem =
                std::string(kinds[kind].what) + ": " + httplib::to_string(result.error());
          }
        } else if (result->status != kinds[kind].status) {
          ++wrong_status;
          if (first_problem.empty()) {
            first_problem = std::string(kinds[kind].what) + ": " + std::to_string(result->status) +
                            " " + result->body;
          }
        }
        if (++done == 100) rss_after_100 = ResidentMiB(server_->pid());
      }
    });
  }
  for (std::thread& client : clients) client.join();
  const double seconds = SecondsSince(start);
  const double rss_end = ResidentMiB(server_->pid());
  std::printf(
      "%d requests from %d clients in %.1f s (%.0f/s); RSS %.1f MiB after 100, %.1f MiB "
      "after all\n",
      kRequests, kClients, seconds, kRequests / seconds, rss_after_100.load(), rss_end);
  for (size_t kind = 0; kind < kinds.size(); ++kind) {
    std::vector<double>& t = times_ms[kind];
    std::sort(t.begin(), t.end());
    std::printf("  %-26s %4zu  p50 %7.1f ms  p95 %7.1f ms\n", kinds[kind].what, t.size(),
                t[t.size() / 2], t[t.size() * 95 / 100]);
  }
  EXPECT_EQ(failed, 0) << first_problem;
  EXPECT_EQ(wrong_status, 0) << first_problem;
  ASSERT_GT(rss_after_100.load(), 0.0);
  EXPECT_LE(rss_end, 1.10 * rss_after_100.load());
  ExpectStillServing();
}

TEST_F(ServeTest, SlowClientsDoNotStarveHealth) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  std::vector<int> slow;
  for (int i = 0; i < 16; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(server_->port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
    const std::string half = "GET /health HTTP/1.1\r\nHost: x\r\n";
    ::send(fd, half.data(), half.size(), MSG_NOSIGNAL);
    slow.push_back(fd);
  }
  // The server counts a request once it has answered it, so a request of the test before (the
  // load test's last /locate, 2.4 s) can still be counted after its client moved on: read until
  // each read adds just itself.
  nlohmann::json before = Json(Client().Get("/health"));
  for (int i = 0; i < 50; ++i) {
    const nlohmann::json next = Json(Client().Get("/health"));
    const bool settled = next["requests"].get<int>() == before["requests"].get<int>() + 1;
    before = next;
    if (settled) break;
  }
  EXPECT_EQ(
      RawStatusLine(server_->port(), "GET /health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
                    std::chrono::seconds(3), /*until_closed=*/true),
      "HTTP/1.1 200 OK");
  // The half-sent requests are still open: counted are the first /health and the raw one.
  const nlohmann::json after = Json(Client().Get("/health"));
  for (const int fd : slow) ::close(fd);
  EXPECT_EQ(after["requests"].get<int>(), before["requests"].get<int>() + 2) << after.dump();
  EXPECT_GT(after["request_p95_ms"].get<double>(), 0.0) << after.dump();
  EXPECT_GE(after["request_p95_ms"].get<double>(), after["request_p50_ms"].get<double>());
}

// A second server on the suite's port fails at start, saying so: the port is not shared.
TEST_F(ServeTest, ASecondServerOnTheSamePortFailsAtStart) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  const testing::CommandResult second =
      testing::RunCommand(SIGHTMAP_BINARY, "serve --model " + (*dir_ / "model.db").string() +
                                               " --port " + std::to_string(server_->port()));
  EXPECT_EQ(second.exit_code, 1);
  EXPECT_NE(second.err.find("port " + std::to_string(server_->port()) + " on 127.0.0.1 is in use"),
            std::string::npos)
      << second.err;
  // Said before the model is read: a large model takes seconds to load.
  EXPECT_EQ(second.err.find("loading"), std::string::npos) << second.err;
  ExpectStillServing();
}

// `sightmap eval identify` on the same model and photos (the binary, as scripts run it).
TEST_F(ServeTest, EvalIdentifyReportsThePapersFigures) {
  const std::string model = (*dir_ / "model.db").string();
  const std::string plot = (*dir_ / "identify.png").string();
  const std::string rows = (*dir_ / "photos.jsonl").string();
  const testing::CommandResult json = testing::RunCommand(
      SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " +
                           (*dir_ / "queries").string() + " --limit 6 --json --plot " + plot +
                           " --photos-out " + rows);
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const nlohmann::json e = nlohmann::json::parse(json.out, nullptr, false);
  for (const char* key : {"photos", "matched_ratio", "recall_ge_0_8_ratio",
                          "precision_ge_0_8_ratio", "occluded_false_positive_ratio",
                          "locate_median_ms", "locate_p95_ms", "categories", "stages_ms"}) {
    EXPECT_TRUE(e.contains(key)) << key << " in " << json.out;
  }
  EXPECT_EQ(e["photos"], 6);
  EXPECT_GT(e["locate_median_ms"].get<double>(), 0.0);
  // Which matching kernel the timings came from: this CPU's fastest.
  EXPECT_EQ(e["match_kernel"], slam::KernelName(slam::FastestKernel()));
  EXPECT_NE(e["match_kernel"], "fastest");
  EXPECT_NE(json.err.find("6/6 photos"), std::string::npos) << json.err;  // progress
  const cv::Mat image = cv::imread(plot);
  EXPECT_EQ(image.cols, 1200);
  // One line per photo, matched as the summary counts them.
  std::ifstream rows_file(rows);
  int lines = 0;
  int matched = 0;
  for (std::string line; std::getline(rows_file, line); ++lines) {
    const nlohmann::json row = nlohmann::json::parse(line, nullptr, false);
    ASSERT_FALSE(row.is_discarded()) << line;
    EXPECT_EQ(row["index"], lines) << line;
    matched += row["matched"].get<bool>() ? 1 : 0;
    EXPECT_EQ(row["matched"].get<bool>(), row["reason"].is_null()) << line;
    EXPECT_EQ(row["matched"].get<bool>(), row["wrong_pose"].is_boolean()) << line;
  }
  EXPECT_EQ(lines, 6);
  EXPECT_EQ(matched, e["matched_photos"].get<int>());
  EXPECT_EQ(e["seeing_keyframes_first"], false);
  // With the keyframes that saw each view searched first, retrieval ranks one of them first
  // wherever the model has one.
  const testing::CommandResult oracle = testing::RunCommand(
      SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " +
                           (*dir_ / "queries").string() +
                           " --limit 6 --json --seeing-keyframes-first --photos-out " + rows);
  ASSERT_EQ(oracle.exit_code, 0) << oracle.err;
  EXPECT_EQ(nlohmann::json::parse(oracle.out)["seeing_keyframes_first"], true);
  std::ifstream oracle_rows(rows);
  int seen_views = 0;
  for (std::string line; std::getline(oracle_rows, line);) {
    const nlohmann::json row = nlohmann::json::parse(line);
    if (row["seeing_keyframes"].get<int>() == 0) continue;
    ++seen_views;
    EXPECT_EQ(row["retrieval_rank"], 1) << line;
  }
  EXPECT_GT(seen_views, 0);
  // The queries/ folder itself is accepted too; the human table names the figures.
  const testing::CommandResult table = testing::RunCommand(
      SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " +
                           (*dir_ / "queries" / "queries").string() + " --limit 2");
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("photos matched"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("occluded reported as visible"), std::string::npos) << table.out;
  const testing::CommandResult missing = testing::RunCommand(
      SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " + dir_->string());
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("no queries.json"), std::string::npos) << missing.err;
  // --config sets the locator's options: no photo reaches 100,000 inliers; an unknown key is a
  // usage error naming the file and the key.
  const std::string strict = (*dir_ / "strict.json").string();
  std::ofstream(strict) << R"({"min_inliers": 100000, "confident_inliers": 100000})";
  const testing::CommandResult refused = testing::RunCommand(
      SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " +
                           (*dir_ / "queries").string() + " --limit 2 --json --config " + strict);
  ASSERT_EQ(refused.exit_code, 0) << refused.err;
  EXPECT_EQ(nlohmann::json::parse(refused.out)["matched_photos"], 0);
  const std::string typo = (*dir_ / "typo.json").string();
  std::ofstream(typo) << R"({"min_inlier": 10})";
  const testing::CommandResult bad =
      testing::RunCommand(SIGHTMAP_BINARY, "eval identify --model " + model + " --queries " +
                                               (*dir_ / "queries").string() + " --config " + typo);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--config " + typo), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("min_inlier"), std::string::npos) << bad.err;
}

// Last (gtest runs a file's tests in order): SIGTERM stops the suite's server cleanly.
TEST_F(ServeTest, SigtermStopsCleanly) {
  ASSERT_GT(server_->port(), 0) << server_->output();
  EXPECT_EQ(server_->StopWith(SIGTERM, std::chrono::seconds(10)), 0) << server_->output();
  EXPECT_NE(server_->output().find("stopped"), std::string::npos) << server_->output();
  EXPECT_FALSE(Client().Get("/health"));
}

TEST(Serve, BusyPortAndMissingModelFailWithOneLine) {
  const testing::CommandResult missing =
      testing::RunCommand(SIGHTMAP_BINARY, "serve --model /nonexistent/model.db --port 0");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("error: "), std::string::npos) << missing.err;
  const testing::CommandResult usage = testing::RunCommand(SIGHTMAP_BINARY, "serve --port 0");
  EXPECT_EQ(usage.exit_code, 2);
}

}  // namespace
}  // namespace sightmap
