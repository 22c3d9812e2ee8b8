#include "store/point_cloud.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <array>
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
#include "core/input_file.h"
#include "core/options_json.h"
#include "core/voxel_key.h"

namespace sightmap::store {
namespace {

// Back-projected points are summed per voxel as they arrive (a voxel grid's answer: each voxel's
// centroid and mean colour), so a 3,000-keyframe model never holds its tens of millions of raw
// points at once (a filter run on the raw cloud, refiltered whenever it doubled, peaked at 1.5 GB).
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

// The points as nanoflann's k-d tree reads them.
struct PointsAdaptor {
  const std::vector<ColoredPoint>& points;
  size_t kdtree_get_point_count() const { return points.size(); }
  float kdtree_get_pt(size_t index, size_t dim) const { return points[index].position[dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box& /*box*/) const {
    return false;
  }
};

// Statistical outlier removal (as PCL's, which this replaced, with the same points kept on a
// 90-keyframe model: 551,204): each point's mean distance to its
// k nearest neighbours; points whose mean is more than outlier_stddev standard deviations above
// the mean of all are dropped.
std::vector<ColoredPoint> RemoveOutliers(const std::vector<ColoredPoint>& points,
                                         const PlyExportOptions& options) {
  const size_t k = static_cast<size_t>(options.outlier_neighbours);
  if (points.size() <= k) return points;
  using Tree =
      nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointsAdaptor>,
                                          PointsAdaptor, 3>;
  const PointsAdaptor adaptor{points};
  Tree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  std::vector<double> mean_distance(points.size());
  std::vector<uint32_t> indices(k + 1);
  std::vector<float> squared(k + 1);
  for (size_t i = 0; i < points.size(); ++i) {
    // k + 1: the point itself comes first, at distance 0.
    const size_t found =
        tree.knnSearch(points[i].position.data(), k + 1, indices.data(), squared.data());
    double sum = 0.0;
    for (size_t j = 1; j < found; ++j) sum += std::sqrt(static_cast<double>(squared[j]));
    mean_distance[i] = found > 1 ? sum / static_cast<double>(found - 1) : 0.0;
  }
  double mean = 0.0;
  for (const double d : mean_distance) mean += d;
  mean /= static_cast<double>(points.size());
  double variance = 0.0;
  for (const double d : mean_distance) variance += (d - mean) * (d - mean);
  const double stddev = std::sqrt(variance / static_cast<double>(points.size() - 1));
  const double threshold = mean + options.outlier_stddev * stddev;
  std::vector<ColoredPoint> kept;
  kept.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    if (mean_distance[i] <= threshold) kept.push_back(points[i]);
  }
  return kept;
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

// What a point cloud PLY's header says: its vertices' properties in file order, and where they
// start.
struct PlyLayout {
  bool binary = false;
  uint64_t vertices = 0;
  std::vector<std::pair<std::string, std::string>> properties;  // (name, type)
  size_t vertex_bytes = 0;                                      // binary: one vertex's bytes
  size_t header_bytes = 0;                                      // where the body starts
};

// A point cloud's PLY header as ReadPly takes it: one `vertex` element of scalar properties with
// x, y and z, and red, green and blue all three as uchar or none (what the fuzzer found broke the
// reader this replaced is refused here: control characters in the header, partial colours).
PlyLayout ReadPointCloudPlyHeader(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "point cloud", std::ios::binary);
  SIGHTMAP_CHECK(in.is_open(), "cannot read " << path);
  auto fail = [&](const std::string& why) {
    SIGHTMAP_THROW(Error, "cannot read " << path << " as a point cloud PLY: " << why);
  };
  PlyLayout layout;
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
    // A header is plain text: a form feed before "obj_info" (found by ply_fuzzer) is refused.
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
      layout.binary = binary;
      layout.vertices = vertices;
      layout.vertex_bytes = vertex_bytes;
      layout.header_bytes = header_bytes;
      return layout;
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
      layout.properties.emplace_back(name, type);
      vertex_bytes += bytes;
    } else {
      fail("unknown header line '" + line.substr(0, 40) + "'");
    }
  }
  fail("its header has no end_header");
  return layout;
}

// One binary little-endian scalar of `type` at `bytes`, as a double.
double BinaryScalar(const std::string& type, const char* bytes) {
  auto get = [bytes](auto value) {
    std::memcpy(&value, bytes, sizeof(value));
    return static_cast<double>(value);
  };
  if (type == "char" || type == "int8") return get(int8_t{});
  if (type == "uchar" || type == "uint8") return get(uint8_t{});
  if (type == "short" || type == "int16") return get(int16_t{});
  if (type == "ushort" || type == "uint16") return get(uint16_t{});
  if (type == "int" || type == "int32") return get(int32_t{});
  if (type == "uint" || type == "uint32") return get(uint32_t{});
  if (type == "float" || type == "float32") return get(float{});
  return get(double{});
}

// A vertex's values, in property order, to a point (colour 0 when the file has none).
ColoredPoint ToPoint(const std::vector<double>& values, const std::array<int, 6>& slot) {
  ColoredPoint point;
  point.position = Eigen::Vector3f(static_cast<float>(values[static_cast<size_t>(slot[0])]),
                                   static_cast<float>(values[static_cast<size_t>(slot[1])]),
                                   static_cast<float>(values[static_cast<size_t>(slot[2])]));
  if (slot[3] >= 0) {
    point.red = static_cast<uint8_t>(values[static_cast<size_t>(slot[3])]);
    point.green = static_cast<uint8_t>(values[static_cast<size_t>(slot[4])]);
    point.blue = static_cast<uint8_t>(values[static_cast<size_t>(slot[5])]);
  }
  return point;
}

}  // namespace

std::vector<ColoredPoint> ReadPly(const std::string& path) {
  std::error_code ec;
  SIGHTMAP_CHECK(std::filesystem::is_regular_file(path, ec),
                 "cannot read " << path << ": no such file");
  const PlyLayout layout = ReadPointCloudPlyHeader(path);
  // Where x, y, z, red, green, blue are among the properties (-1: no colour).
  std::array<int, 6> slot;
  slot.fill(-1);
  const char* wanted[] = {"x", "y", "z", "red", "green", "blue"};
  for (size_t i = 0; i < layout.properties.size(); ++i) {
    for (size_t w = 0; w < slot.size(); ++w) {
      if (layout.properties[i].first == wanted[w]) slot[w] = static_cast<int>(i);
    }
  }
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(layout.header_bytes));
  std::vector<ColoredPoint> points;
  // No more than the file can hold (an ASCII value takes at least two bytes): a small file that
  // claims a billion vertices must not reserve gigabytes.
  const uint64_t file_bytes = std::filesystem::file_size(path, ec);
  const uint64_t body_bytes =
      !ec && file_bytes > layout.header_bytes ? file_bytes - layout.header_bytes : 0;
  const uint64_t value_bytes = layout.binary ? layout.vertex_bytes : 2 * layout.properties.size();
  points.reserve(static_cast<size_t>(
      std::min<uint64_t>(layout.vertices, body_bytes / std::max<uint64_t>(1, value_bytes))));
  std::vector<double> values(layout.properties.size());
  std::vector<char> record(layout.vertex_bytes);
  for (uint64_t v = 0; v < layout.vertices; ++v) {
    if (layout.binary) {
      in.read(record.data(), static_cast<std::streamsize>(record.size()));
      size_t offset = 0;
      for (size_t i = 0; i < values.size(); ++i) {
        values[i] = BinaryScalar(layout.properties[i].second, record.data() + offset);
        offset += PlyTypeBytes(layout.properties[i].second);
      }
    } else {
      for (double& value : values) in >> value;
    }
    SIGHTMAP_CHECK(in, "cannot read " << path << " as PLY: vertex " << v << " of "
                                      << layout.vertices << " is missing or not numbers");
    points.push_back(ToPoint(values, slot));
  }
  return points;
}

SIGHTMAP_OPTIONS_JSON(PlyExportOptions, pixel_step, min_depth_m, max_depth_m, voxel_size_m,
                      remove_outliers, outlier_neighbours, outlier_stddev)

}  // namespace sightmap::store
