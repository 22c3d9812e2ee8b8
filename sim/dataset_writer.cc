#include "sim/dataset_writer.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/calibration.h"
#include "core/check.h"
#include "core/timing.h"
#include "core/tum_format.h"

namespace sightmap::sim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string TimestampText(TimestampNs ns) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6f", static_cast<double>(ns) * 1e-9);
  return text;
}

void WriteImage(const fs::path& path, const cv::Mat& image, const std::vector<int>& params = {}) {
  SIGHTMAP_CHECK(cv::imwrite(path.string(), image, params),
                 "cannot write " << path.string()
                                 << ": check that the folder is writable and the "
                                    "disk is not full");
}

json PoseJson(const Eigen::Isometry3d& world_from_cam) {
  const Eigen::Quaterniond q(world_from_cam.linear());
  const Eigen::Vector3d t = world_from_cam.translation();
  return {{"position", {t.x(), t.y(), t.z()}}, {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
}

json IntrinsicsJson(const Intrinsics& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx", k.fx},
          {"fy", k.fy},       {"cx", k.cx},         {"cy", k.cy}};
}

std::ofstream OpenText(const fs::path& path) {
  std::ofstream out(path);
  SIGHTMAP_CHECK(out.good(), "cannot write " << path.string());
  return out;
}

}  // namespace

bool GenerateOptions::Check(std::string* error) const {
  if (out_dir.empty()) {
    *error = "out_dir is required";
    return false;
  }
  if (queries < 0) {
    *error = "queries must be >= 0";
    return false;
  }
  return simulator.Check(error) && query.Check(error);
}

namespace {

// The frames as a TUM RGB-D folder: rgb/ and depth/ (5000 units per metre) with their lists and
// groundtruth.txt; progress every 3 s. Returns how many.
int64_t WriteFrames(Simulator& simulator, const fs::path& dir, const std::string& header,
                    std::ostream* progress) {
  std::ofstream rgb_list = OpenText(dir / "rgb.txt");
  std::ofstream depth_list = OpenText(dir / "depth.txt");
  rgb_list << "# color images\n" << header << "\n# timestamp filename\n";
  depth_list << "# depth maps (16-bit PNG, 5000 per metre)\n"
             << header << "\n# timestamp filename\n";
  std::vector<StampedPose> groundtruth;
  auto last_report = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < simulator.num_frames(); ++i) {
    const RgbdFrame frame = simulator.RenderFrame(i);
    const std::string stamp = TimestampText(frame.timestamp_ns);
    WriteImage(dir / "rgb" / (stamp + ".png"), frame.color);
    cv::Mat depth_tum;
    frame.depth.convertTo(depth_tum, CV_16U, 5.0);  // mm -> 1/5000 m
    WriteImage(dir / "depth" / (stamp + ".png"), depth_tum);
    rgb_list << stamp << " rgb/" << stamp << ".png\n";
    depth_list << stamp << " depth/" << stamp << ".png\n";
    groundtruth.push_back({frame.timestamp_ns, *frame.world_from_cam_gt});
    const auto now = std::chrono::steady_clock::now();
    if (progress != nullptr && now - last_report > std::chrono::seconds(3)) {
      last_report = now;
      *progress << "sim: frame " << (i + 1) << "/" << simulator.num_frames() << "\n" << std::flush;
    }
  }
  SIGHTMAP_CHECK(rgb_list.good() && depth_list.good(),
                 "cannot write the TUM lists in " << dir.string());
  WriteTumTrajectory((dir / "groundtruth.txt").string(), groundtruth,
                     "ground truth trajectory; " + header.substr(2));
  return static_cast<int64_t>(groundtruth.size());
}

// calibration.json (the one camera for colour and depth) and appliances.json (the scene's labels).
void WriteCalibrationAndAppliances(const Scene& scene, const Intrinsics& camera,
                                   const fs::path& dir) {
  capture::RgbdCalibration calibration;
  calibration.color = camera;
  calibration.depth = camera;
  calibration.color_from_depth = Eigen::Isometry3d::Identity();
  capture::WriteCalibrationFile((dir / "calibration.json").string(), calibration);
  json appliances = json::array();
  for (const Appliance& a : scene.appliances) {
    json points = json::array();
    for (const Eigen::Vector3d& p : a.points) points.push_back({p.x(), p.y(), p.z()});
    appliances.push_back({{"id", a.id}, {"name", a.name}, {"type", a.type}, {"points", points}});
  }
  OpenText(dir / "appliances.json")
      << json{{"scene", scene.name}, {"appliances", appliances}}.dump(1) << "\n";
}

// One photo's entry in queries.json: its truth and what it shows of each appliance.
json QueryJson(const Scene& scene, const QueryPhoto& photo, const std::string& image) {
  json types = json::object();
  json details = json::array();
  for (const ApplianceVisibility& v : photo.visibility) {
    const std::string& appliance_name =
        scene.appliances[static_cast<size_t>(v.appliance_id - 1)].name;
    types[appliance_name] = ToString(v.type);
    details.push_back({{"id", v.appliance_id},
                       {"name", appliance_name},
                       {"type", ToString(v.type)},
                       {"footprint_px", v.footprint_px},
                       {"in_image_px", v.in_image_px},
                       {"visible_px", v.visible_px}});
  }
  return {{"image", image},
          {"intrinsics", IntrinsicsJson(photo.intrinsics)},
          {"world_from_cam", PoseJson(photo.world_from_cam)},
          {"target", scene.appliances[static_cast<size_t>(photo.target_appliance - 1)].name},
          {"with_occluder", photo.with_occluder},
          {"types", types},
          {"visibility", details}};
}

// The photos as queries/NNNN.jpg with queries/queries.json.
void WriteQueries(const Scene& scene, const std::vector<QueryPhoto>& photos,
                  const VisibilityThresholds& thresholds, const fs::path& dir) {
  json queries = json::array();
  for (const QueryPhoto& photo : photos) {
    char name[32];
    std::snprintf(name, sizeof(name), "%04d.jpg", photo.index);
    WriteImage(dir / "queries" / name, photo.image, {cv::IMWRITE_JPEG_QUALITY, 92});
    queries.push_back(QueryJson(scene, photo, std::string("queries/") + name));
  }
  const VisibilityThresholds& t = thresholds;
  OpenText(dir / "queries" / "queries.json")
      << json{{"thresholds",
               {{"id_buffer_downscale", t.id_buffer_downscale},
                {"min_pixels", t.min_pixels},
                {"occluded_below", t.occluded_below},
                {"visible_from", t.visible_from}}},
              {"queries", queries}}
             .dump(1)
      << "\n";
}

// overview.png: the floor plan with the whole walk at 2 Hz (not just the written frames, sparse
// at --fps 1) and the photos.
void WriteOverview(const Simulator& simulator, const std::vector<QueryPhoto>& photos,
                   const fs::path& dir) {
  std::vector<Eigen::Isometry3d> walk;
  const double duration_s =
      static_cast<double>(simulator.TimestampOf(simulator.num_frames())) * 1e-9;
  for (double time_s = 0.0; time_s <= duration_s; time_s += 0.5) {
    walk.push_back(simulator.trajectory().WorldFromCam(time_s));
  }
  WriteImage(dir / "overview.png", DrawOverview(simulator.scene(), walk, photos));
}

}  // namespace

GenerateSummary GenerateDataset(const GenerateOptions& options, std::ostream* progress) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  const fs::path dir = options.out_dir;
  std::error_code ec;
  fs::create_directories(dir / "rgb", ec);
  fs::create_directories(dir / "depth", ec);
  fs::create_directories(dir / "queries", ec);
  SIGHTMAP_CHECK(!ec && fs::is_directory(dir / "rgb"),
                 "cannot create " << (dir / "rgb").string() << ": " << ec.message());

  Simulator simulator(options.simulator);
  const SimulatorOptions& so = options.simulator;
  const std::string header = std::string("# sightmap synthetic building: scene ") + so.scene +
                             ", trajectory " + ToString(so.trajectory) + ", session " +
                             std::to_string(so.session) + ", seed " + std::to_string(so.seed);
  GenerateSummary summary;
  summary.frames = WriteFrames(simulator, dir, header, progress);
  WriteCalibrationAndAppliances(simulator.scene(), so.camera, dir);
  if (progress != nullptr && options.queries > 0) {
    *progress << "sim: rendering " << options.queries << " phone photos\n" << std::flush;
  }
  const std::vector<QueryPhoto> photos = simulator.MakeQueries(options.queries, options.query);
  WriteQueries(simulator.scene(), photos, options.query.thresholds, dir);
  WriteOverview(simulator, photos, dir);
  summary.queries = static_cast<int>(photos.size());
  summary.seconds = SecondsSince(start);
  summary.frames_per_second = summary.seconds > 0 ? summary.frames / summary.seconds : 0.0;
  return summary;
}

}  // namespace sightmap::sim
