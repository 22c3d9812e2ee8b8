// Writes the fuzzers' seed corpora (SIGHTMAP_FUZZ_SEED_DIR/<fuzzer>/) from the project's own
// writers and real files, and checks that each seed is a valid input, so the fuzzers start from
// the inside of each format. scripts/fuzz.sh runs the fuzzers on them.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/calibration.h"
#include "capture/folder_source.h"
#include "cli/locate_server.h"
#include "core/options_json.h"
#include "fuzz/fuzz_inputs.h"
#include "identify/exif_testing.h"
#include "identify/photo.h"
#include "mapping/mapping_session.h"
#include "sim/scene.h"
#include "store/label_files.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/synthetic_model.h"

namespace sightmap {
namespace {

namespace fs = std::filesystem;

std::string SeedDir(const std::string& fuzzer) {
  const fs::path dir = fs::path(SIGHTMAP_FUZZ_SEED_DIR) / fuzzer;
  fs::create_directories(dir);
  return dir.string();
}

std::string Bytes(const std::vector<uint8_t>& bytes) {
  return std::string(bytes.begin(), bytes.end());
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A real photo: a textured 320x240 image, so the decoder and ORB have work to do.
cv::Mat TestImage() {
  cv::Mat image(240, 320, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::rectangle(image, cv::Rect(40, 30, 120, 90), cv::Scalar(20, 200, 90), cv::FILLED);
  return image;
}

TEST(FuzzSeeds, SceneJson) {
  const std::string dir = SeedDir("scene_json");
  const std::string office = sim::OfficeSceneJson();
  fuzz::WriteFile(dir + "/office.json", office);
  EXPECT_FALSE(sim::ParseScene(office, "office").appliances.empty());
}

TEST(FuzzSeeds, CalibrationJson) {
  const std::string dir = SeedDir("calibration_json");
  capture::RgbdCalibration full;
  full.color = Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
  full.depth = Intrinsics::FromPinhole(640, 480, 575.8, 575.8, 319.5, 239.5);
  full.color_from_depth = Eigen::Isometry3d(Eigen::Translation3d(0.025, 0.0, 0.0));
  capture::WriteCalibrationFile(dir + "/full.json", full);
  capture::RgbdCalibration colour_only;
  colour_only.color = full.color;
  capture::WriteCalibrationFile(dir + "/color.json", colour_only);
  EXPECT_TRUE(capture::ReadCalibrationFile(dir + "/full.json").color_from_depth.has_value());
}

TEST(FuzzSeeds, OptionsJson) {
  const std::string dir = SeedDir("options_json");
  std::ofstream(dir + "/map.json") << nlohmann::json(mapping::MappingOptions()).dump(2);
  std::ofstream(dir + "/serve.json") << nlohmann::json(cli::LocateServerOptions()).dump(2);
  std::ofstream(dir + "/partial.json") << R"({"mapper": {"pose_graph": {"max_iterations": 7}}})";
  std::ofstream(dir + "/overflow.json") << "22e888";  // a crash the fuzzer found
  EXPECT_GT(std::filesystem::file_size(dir + "/map.json"), 1000u);
}

TEST(FuzzSeeds, TumFolderLists) {
  const std::string dir = SeedDir("tum_folder");
  const std::string rgb =
      "# color images\n1305031102.175304 rgb/0.png\n1305031102.211214 rgb/1.png\n";
  const std::string depth =
      "# depth maps\n1305031102.160407 depth/0.png\n1305031102.194330 depth/1.png\n";
  const std::string truth =
      "# timestamp tx ty tz qx qy qz qw\n1305031102.1600 1.3 0.6 1.6 0.65 0.62 -0.29 -0.32\n"
      "1305031102.2200 1.3 0.6 1.6 0.65 0.62 -0.29 -0.32\n";
  fuzz::WriteFile(dir + "/two-frames", fuzz::JoinParts({rgb, depth, truth}));
  fuzz::WriteFile(dir + "/no-truth", fuzz::JoinParts({rgb, depth, ""}));
}

TEST(FuzzSeeds, ThreeDMatchText) {
  const std::string dir = SeedDir("threedmatch_folder");
  const std::string intrinsics = "585 0 320\n0 585 240\n0 0 1\n";
  const std::string pose = "1 0 0 0.1\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  fuzz::WriteFile(dir + "/two-poses", fuzz::JoinParts({intrinsics, pose, pose}));
  fuzz::WriteFile(dir + "/no-pose", fuzz::JoinParts({intrinsics, "", ""}));
}

TEST(FuzzSeeds, PointLists) {
  const std::string dir = SeedDir("point_list");
  store::WritePointList(dir + "/written.txt", {{1.0, 2.0, 0.5}, {-0.25, 1.5, 2.0}});
  fuzz::WriteFile(dir + "/cloudcompare.asc", "//X,Y,Z,R,G,B\n1.5,2.25,0.75,255,0,0\n2,3,1,0,0,0\n");
  EXPECT_EQ(store::ReadPointList(dir + "/written.txt").size(), 2u);
}

TEST(FuzzSeeds, LabelRequests) {
  const std::string dir = SeedDir("label_request");
  fuzz::WriteFile(
      dir + "/add",
      R"({"name": "projector 1", "type": "projector", "keyframe": 1, "pixel": [20, 30]})");
  fuzz::WriteFile(dir + "/rename", R"({"name": "desk lamp", "type": "lamp"})");
  fuzz::WriteFile(dir + "/bad-pixel", R"({"name": "x", "keyframe": 1, "pixel": [1e300, -4]})");
  EXPECT_FALSE(nlohmann::json::parse(ReadBytes(dir + "/add")).is_discarded());
}

TEST(FuzzSeeds, Photos) {
  const std::string dir = SeedDir("photo");
  const cv::Mat image = TestImage();
  testing::ExifFields portrait;
  portrait.orientation = 6;
  portrait.focal_35mm = 26;
  testing::ExifFields sensor;
  sensor.focal_mm = 4.25;
  sensor.plane_x_resolution = 4000.0;
  sensor.plane_y_resolution = 4000.0;
  sensor.plane_unit = 3;
  sensor.order = EXIF_BYTE_ORDER_MOTOROLA;
  fuzz::WriteFile(dir + "/portrait.jpg", Bytes(testing::JpegWithExif(image, portrait)));
  fuzz::WriteFile(dir + "/sensor.jpg", Bytes(testing::JpegWithExif(image, sensor)));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  fuzz::WriteFile(dir + "/plain.png", Bytes(png));
  const std::string jpeg = ReadBytes(dir + "/portrait.jpg");
  const identify::Photo photo = identify::DecodePhoto(reinterpret_cast<const uint8_t*>(jpeg.data()),
                                                      jpeg.size(), identify::kMaxPhotoMegapixels);
  EXPECT_EQ(photo.orientation.exif_code, 6);
}

TEST(FuzzSeeds, Ply) {
  const std::string dir = SeedDir("ply");
  store::Model model = store::Model::Open(":memory:");
  store::SyntheticKeyframeOptions options;
  options.width = 64;
  options.height = 48;
  options.num_features = 10;
  const SessionId session = model.BeginSession({});
  model.AddKeyframe(store::MakeSyntheticKeyframe(session, 0, options));
  store::PlyExportOptions ply;
  ply.voxel_size_m = 0.2;
  store::ExportPly(model, dir + "/wall.ply", ply);
  const std::vector<store::ColoredPoint> points = store::ReadPly(dir + "/wall.ply");
  EXPECT_GT(points.size(), 3u);
  EXPECT_LT(fs::file_size(dir + "/wall.ply"), 20000u);
}

// locate_request_fuzzer reads its input with FuzzedDataProvider: the query string (ended by a
// backslash and one more byte), the body, and from the end the Content-Type and the length mode
// (Content-Length, none, -5, huge, chunked; one byte each, modulo 5) and the route (modulo 6: 0
// POST /locate, 1 POST /api/labels, 2 PATCH and 3 DELETE /api/labels/1, 4 a keyframe image, 5 a
// keyframe's labels).
std::string LocateRequestSeed(const std::string& query, const std::string& body, int type,
                              int length_mode, int route = 0) {
  return query + "\\q" + body + static_cast<char>(route) + static_cast<char>(length_mode) +
         static_cast<char>(type);
}

TEST(FuzzSeeds, LocateRequests) {
  const std::string dir = SeedDir("locate_request");
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", TestImage(), jpeg));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", TestImage(), png));
  const std::string intrinsics = "fx=300&fy=300&cx=159.5&cy=119.5";
  fuzz::WriteFile(dir + "/jpeg", LocateRequestSeed("", Bytes(jpeg), 1, 0));
  fuzz::WriteFile(dir + "/jpeg-intrinsics", LocateRequestSeed(intrinsics, Bytes(jpeg), 1, 0));
  fuzz::WriteFile(dir + "/png-untyped", LocateRequestSeed("", Bytes(png), 0, 0));
  fuzz::WriteFile(dir + "/multipart", LocateRequestSeed("", Bytes(jpeg), 3, 0));
  fuzz::WriteFile(dir + "/cut", LocateRequestSeed("", Bytes(jpeg).substr(0, 2000), 1, 0));
  fuzz::WriteFile(dir + "/chunked", LocateRequestSeed("fx=1", Bytes(jpeg), 2, 4));
  const std::string add = R"({"name": "lamp", "type": "lamp", "keyframe": 1, "pixel": [100, 80]})";
  fuzz::WriteFile(dir + "/label-add", LocateRequestSeed("", add, 0, 0, 1));
  fuzz::WriteFile(dir + "/label-rename",
                  LocateRequestSeed("token=x", R"({"name": "desk lamp"})", 0, 0, 2));
  fuzz::WriteFile(dir + "/label-remove", LocateRequestSeed("", "", 0, 1, 3));
  fuzz::WriteFile(dir + "/keyframe-image", LocateRequestSeed("max_side=64", "", 0, 1, 4));
  fuzz::WriteFile(dir + "/keyframe-labels", LocateRequestSeed("", "", 0, 1, 5));
}

}  // namespace
}  // namespace sightmap
