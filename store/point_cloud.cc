// The only file of sightmap that includes PCL: its headers are heavy to compile, and keeping them
// here keeps PCL a private dependency of sightmap_store.
#include "store/point_cloud.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "core/atomic_file.h"
#include "core/check.h"
#include "core/voxel_key.h"

namespace sightmap {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZRGB>;

// Back-projected points are summed per voxel as they arrive (PCL's VoxelGrid answer: each voxel's
// centroid and mean colour), so a 3,000-keyframe model never holds its tens of millions of raw
// points at once: PCL's filter on the raw cloud, refiltered whenever it doubled, peaked at 1.5 GB.
class VoxelAccumulator {
 public:
  // leaf_m 0 keeps every point: each gets its own key.
  explicit VoxelAccumulator(double leaf_m) : leaf_m_(leaf_m) {}

  void Add(const Eigen::Vector3f& world, const cv::Vec3b& bgr) {
    Sum sum;
    Eigen::Vector3f offset = world;
    if (leaf_m_ > 0.0) {
      const Eigen::Vector3d point = world.cast<double>();
      const std::optional<uint64_t> key = VoxelKeyOf(point, leaf_m_);
      if (!key) return;  // beyond +-21 km (at 2 cm): a depth glitch on a wild pose
      sum.key = *key;
      offset = (point - VoxelCorner(*key, leaf_m_)).cast<float>();
    } else {
      sum.key = sums_.size();  // never merged
    }
    sum.dx = offset.x();
    sum.dy = offset.y();
    sum.dz = offset.z();
    sum.count = 1;
    sum.blue = bgr[0];
    sum.green = bgr[1];
    sum.red = bgr[2];
    sums_.push_back(sum);
    if (leaf_m_ > 0.0 && sums_.size() >= merge_at_) Merge();
  }

  // Voxels (or points, at leaf 0) in key order, each as its centroid and mean colour.
  std::vector<ColoredPoint> Points() {
    Merge();
    std::vector<ColoredPoint> points;
    points.reserve(sums_.size());
    for (const Sum& sum : sums_) {
      const Eigen::Vector3d corner =
          leaf_m_ > 0.0 ? VoxelCorner(sum.key, leaf_m_) : Eigen::Vector3d::Zero();
      const double n = sum.count;
      ColoredPoint point;
      point.position = (corner + Eigen::Vector3d(sum.dx, sum.dy, sum.dz) / n).cast<float>();
      point.red = static_cast<uint8_t>(std::lround(sum.red / n));
      point.green = static_cast<uint8_t>(std::lround(sum.green / n));
      point.blue = static_cast<uint8_t>(std::lround(sum.blue / n));
      points.push_back(point);
    }
    std::vector<Sum>().swap(sums_);
    return points;
  }

 private:
  // Offsets from the voxel's corner keep the float sums small: exact to about 0.1 mm over 10^5
  // points of a 2 cm voxel.
  struct Sum {
    uint64_t key = 0;
    float dx = 0.0f;
    float dy = 0.0f;
    float dz = 0.0f;
    uint32_t count = 0;
    uint32_t blue = 0;
    uint32_t green = 0;
    uint32_t red = 0;
  };
  // Sums are merged (sorted by key, equal keys added) once they reach this many, and after that
  // whenever they have grown by half since: memory stays within 1.5x the voxels, and each merge
  // of n sums follows at least n/3 new points, so all merges cost O(points x log voxels).
  static constexpr size_t kFirstMerge = 1'000'000;

  void Merge() {
    if (leaf_m_ <= 0.0 || sums_.empty()) return;
    std::sort(sums_.begin(), sums_.end(), [](const Sum& a, const Sum& b) { return a.key < b.key; });
    size_t out = 0;
    for (size_t i = 1; i < sums_.size(); ++i) {
      Sum& kept = sums_[out];
      const Sum& next = sums_[i];
      if (next.key == kept.key) {
        kept.dx += next.dx;
        kept.dy += next.dy;
        kept.dz += next.dz;
        kept.count += next.count;
        kept.blue += next.blue;
        kept.green += next.green;
        kept.red += next.red;
      } else {
        sums_[++out] = next;
      }
    }
    sums_.resize(out + 1);
    merge_at_ = std::max(kFirstMerge, sums_.size() + sums_.size() / 2);
  }

  double leaf_m_;
  std::vector<Sum> sums_;
  size_t merge_at_ = kFirstMerge;
};

// Binary little-endian PLY, x y z (float) red green blue (uchar), through an AtomicFile: a crash or
// a full disk never leaves a truncated cloud under the name.
void WritePly(const std::string& path, const std::vector<ColoredPoint>& points) {
  static_assert(sizeof(float) == 4, "PLY floats are 4 bytes");
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
                "records are copied as they lie in memory");
  AtomicFile file(path, ".partial");
  std::ostream& out = file.out();
  out << "ply\nformat binary_little_endian 1.0\ncomment written by sightmap\nelement vertex "
      << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
         "property uchar green\nproperty uchar blue\nend_header\n";
  std::vector<char> buffer;
  constexpr size_t kRecord = 15;
  constexpr size_t kBatch = 1 << 16;
  buffer.reserve(kRecord * kBatch);
  for (size_t i = 0; i < points.size(); i += kBatch) {
    buffer.clear();
    for (size_t j = i; j < std::min(points.size(), i + kBatch); ++j) {
      const ColoredPoint& p = points[j];
      char record[kRecord];
      std::memcpy(record, p.position.data(), 12);
      record[12] = static_cast<char>(p.red);
      record[13] = static_cast<char>(p.green);
      record[14] = static_cast<char>(p.blue);
      buffer.insert(buffer.end(), record, record + kRecord);
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
  file.Commit();
}

std::vector<ColoredPoint> ToColoredPoints(const Cloud& cloud) {
  std::vector<ColoredPoint> points;
  points.reserve(cloud.size());
  for (const pcl::PointXYZRGB& p : cloud) {
    ColoredPoint point;
    point.position = Eigen::Vector3f(p.x, p.y, p.z);
    point.red = p.r;
    point.green = p.g;
    point.blue = p.b;
    points.push_back(point);
  }
  return points;
}

// PCL's statistical outlier removal, on the voxel centres.
std::vector<ColoredPoint> RemoveOutliers(const std::vector<ColoredPoint>& points,
                                         const PlyExportOptions& options) {
  auto cloud = std::make_shared<Cloud>();
  cloud->reserve(points.size());
  for (const ColoredPoint& p : points) {
    pcl::PointXYZRGB point;
    point.x = p.position.x();
    point.y = p.position.y();
    point.z = p.position.z();
    point.r = p.red;
    point.g = p.green;
    point.b = p.blue;
    cloud->push_back(point);
  }
  pcl::StatisticalOutlierRemoval<pcl::PointXYZRGB> removal;
  removal.setInputCloud(cloud);
  removal.setMeanK(options.outlier_neighbours);
  removal.setStddevMulThresh(options.outlier_stddev);
  Cloud kept;
  removal.filter(kept);
  return ToColoredPoints(kept);
}

}  // namespace

bool PlyExportOptions::Check(std::string* error) const {
  auto fail = [error](const char* message) {
    if (error) *error = message;
    return false;
  };
  if (pixel_step < 1) return fail("pixel_step must be >= 1 px");
  if (!(min_depth_m >= 0.0 && max_depth_m > min_depth_m)) {
    return fail("depth range must satisfy 0 <= min_depth_m < max_depth_m");
  }
  if (!(voxel_size_m >= 0.0)) return fail("voxel_size_m must be >= 0 m (0 disables it)");
  if (outlier_neighbours < 1) return fail("outlier_neighbours must be >= 1");
  if (!(outlier_stddev > 0.0)) return fail("outlier_stddev must be > 0");
  return true;
}

PlyExportStats ExportPly(const Model& model, const std::string& path,
                         const PlyExportOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const std::vector<KeyframeInfo> keyframes = model.Keyframes();
  SIGHTMAP_CHECK(!keyframes.empty(), "model "
                                         << model.path()
                                         << " has no keyframes: there is no point cloud to export");
  PlyExportStats stats;
  VoxelAccumulator voxels(options.voxel_size_m);
  const uint16_t min_mm = static_cast<uint16_t>(std::ceil(options.min_depth_m * 1000.0));
  const double max_mm = options.max_depth_m * 1000.0;
  for (const KeyframeInfo& keyframe : keyframes) {
    const cv::Mat depth = model.LoadDepth(keyframe.id);
    const cv::Mat color = model.LoadColor(keyframe.id);
    SIGHTMAP_CHECK(depth.size() == color.size(), "keyframe "
                                                     << keyframe.id.value()
                                                     << " has colour and depth of different sizes");
    const Intrinsics& k = keyframe.intrinsics;
    const Eigen::Isometry3f world_from_cam = keyframe.world_from_cam.cast<float>();
    for (int v = 0; v < depth.rows; v += options.pixel_step) {
      const auto* depth_row = depth.ptr<uint16_t>(v);
      const auto* color_row = color.ptr<cv::Vec3b>(v);
      for (int u = 0; u < depth.cols; u += options.pixel_step) {
        const uint16_t z_mm = depth_row[u];
        if (z_mm == 0 || z_mm < min_mm || z_mm > max_mm) continue;
        voxels.Add(world_from_cam * k.Unproject(u, v, z_mm * 1e-3).cast<float>(), color_row[u]);
        ++stats.back_projected_points;
      }
    }
    ++stats.keyframes;
  }
  std::vector<ColoredPoint> points = voxels.Points();
  if (options.remove_outliers && points.size() > static_cast<size_t>(options.outlier_neighbours)) {
    points = RemoveOutliers(points, options);
  }
  SIGHTMAP_CHECK(!points.empty(), "no keyframe of model "
                                      << model.path() << " has depth within ["
                                      << options.min_depth_m << ", " << options.max_depth_m
                                      << "] m: there is no point cloud to export");
  WritePly(path, points);
  stats.written_points = static_cast<int64_t>(points.size());
  return stats;
}

namespace {

// Bytes of a PLY scalar type, 0 for an unknown name.
size_t PlyTypeBytes(const std::string& type) {
  static const std::map<std::string, size_t> kBytes = {
      {"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},  {"short", 2}, {"ushort", 2},
      {"int16", 2}, {"uint16", 2},  {"int", 4},    {"uint", 4},   {"int32", 4}, {"uint32", 4},
      {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  const auto it = kBytes.find(type);
  return it == kBytes.end() ? 0 : it->second;
}

// A point cloud's PLY header as ReadPly takes it: one `vertex` element of scalar properties with
// x, y and z, and red, green and blue all three as uchar or none. Checked before PCL sees the
// file: PCL's reader asserts (aborts the process) on some colour layouts, which the fuzzer found.
void CheckPointCloudPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  SIGHTMAP_CHECK(in.is_open(), "cannot read " << path);
  auto fail = [&](const std::string& why) {
    SIGHTMAP_THROW(Error, "cannot read " << path << " as a point cloud PLY: " << why);
  };
  std::string line;
  if (!std::getline(in, line) || (line != "ply" && line != "ply\r"))
    fail("it does not start with 'ply'");
  bool binary = false;
  uint64_t vertices = 0;
  int elements = 0;
  size_t vertex_bytes = 0;
  std::set<std::string> names;
  std::map<std::string, std::string> types;
  size_t header_bytes = line.size() + 1;
  constexpr size_t kMaxHeaderBytes = 64 * 1024;
  while (std::getline(in, line)) {
    header_bytes += line.size() + 1;
    if (header_bytes > kMaxHeaderBytes) fail("its header runs past 64 KiB");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // PCL splits header lines on single spaces and asserts on what it did not expect, e.g. a
    // form feed before "obj_info" (found by ply_fuzzer).
    const bool printable = std::all_of(line.begin(), line.end(), [](char c) {
      const auto byte = static_cast<unsigned char>(c);
      return byte >= 0x20 && byte != 0x7F;
    });
    if (!printable || (!line.empty() && line.front() == ' ')) {
      fail("its header has a line with control characters or a leading space");
    }
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "end_header") {
      if (elements != 1) fail("it holds no vertex element");
      for (const char* axis : {"x", "y", "z"}) {
        if (!names.count(axis)) fail(std::string("its vertices have no ") + axis);
      }
      const int colours =
          static_cast<int>(names.count("red") + names.count("green") + names.count("blue"));
      if (colours != 0 && colours != 3) fail("it has some of red, green and blue but not all");
      for (const char* colour : {"red", "green", "blue"}) {
        if (names.count(colour) && types[colour] != "uchar" && types[colour] != "uint8") {
          fail(std::string(colour) + " is not uchar");
        }
      }
      if (binary) {
        std::error_code ec;
        const uint64_t file_bytes = std::filesystem::file_size(path, ec);
        if (ec || file_bytes < header_bytes + vertices * vertex_bytes) {
          fail("it holds fewer bytes than its header says");
        }
      }
      return;
    }
    if (keyword == "comment" || keyword == "obj_info" || keyword.empty()) continue;
    if (keyword == "format") {
      std::string format;
      std::string version;
      words >> format >> version;
      if (format == "binary_little_endian") {
        binary = true;
      } else if (format != "ascii") {
        fail("format '" + format + "' is not read (ascii or binary_little_endian)");
      }
    } else if (keyword == "element") {
      std::string name;
      words >> name >> vertices;
      if (name != "vertex" || !words || elements > 0) fail("its only element must be 'vertex N'");
      if (vertices > 1000000000) fail("it claims more than a billion vertices");
      ++elements;
    } else if (keyword == "property") {
      std::string type;
      std::string name;
      words >> type >> name;
      const size_t bytes = PlyTypeBytes(type);
      if (elements != 1 || bytes == 0 || name.empty() || !names.insert(name).second) {
        fail("property line '" + line + "' is not a scalar vertex property");
      }
      types[name] = type;
      vertex_bytes += bytes;
    } else {
      fail("unknown header line '" + line.substr(0, 40) + "'");
    }
  }
  fail("its header has no end_header");
}

}  // namespace

std::vector<ColoredPoint> ReadPly(const std::string& path) {
  std::error_code ec;
  SIGHTMAP_CHECK(std::filesystem::is_regular_file(path, ec),
                 "cannot read " << path << ": no such file");
  // Read untyped first: PCL's typed conversion indexes the first point of an empty cloud (a PLY
  // whose element is not named "vertex" reads as one), which the fuzzer caught as undefined
  // behaviour; and the fields are checked before they are trusted.
  CheckPointCloudPlyHeader(path);
  pcl::PCLPointCloud2 blob;
  pcl::PLYReader reader;
  const pcl::console::VERBOSITY_LEVEL verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  const int rc = reader.read(path, blob);
  pcl::console::setVerbosityLevel(verbosity);
  SIGHTMAP_CHECK(rc == 0, "cannot read " << path << " as PLY: it is damaged or not a PLY file");
  const uint64_t points = static_cast<uint64_t>(blob.width) * blob.height;
  if (points == 0) return {};
  for (const char* name : {"x", "y", "z"}) {
    SIGHTMAP_CHECK(pcl::getFieldIndex(blob, name) >= 0,
                   "cannot read " << path << " as a point cloud: its vertices have no " << name);
  }
  SIGHTMAP_CHECK(blob.data.size() >= points * blob.point_step,
                 "cannot read " << path << " as PLY: it holds fewer bytes than its header says");
  Cloud cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
  return ToColoredPoints(cloud);
}

}  // namespace sightmap
