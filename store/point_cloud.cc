// The only file of sightmap that includes PCL: its headers are heavy to compile, and keeping them
// here keeps PCL a private dependency of sightmap_store.
#include "store/point_cloud.h"

#include <pcl/common/common.h>
#include <pcl/console/print.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/check.h"

namespace sightmap {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZRGB>;

// Downsampling as points arrive keeps memory bounded on large models: past this many points the
// accumulated cloud is voxel filtered again, and after that whenever it has doubled since the last
// filtering. (Refiltering at a fixed size made a 3,000-keyframe export quadratic: once the
// filtered floor itself held 4M points, every keyframe refiltered all of it.)
constexpr size_t kRefilterPoints = 4'000'000;

// pcl::VoxelGrid indexes voxels with 32-bit ints and returns its input unfiltered when the
// bounding box holds more voxels than that (a 100 m floor at 2 cm does). Larger clouds are cut
// into slabs along x on voxel boundaries, each small enough, and filtered slab by slab.
Cloud::Ptr VoxelFilter(const Cloud::Ptr& cloud, double leaf_m) {
  if (leaf_m <= 0.0 || cloud->empty()) return cloud;
  Eigen::Vector4f lo;
  Eigen::Vector4f hi;
  pcl::getMinMax3D(*cloud, lo, hi);
  const Eigen::Array3d cells = ((hi - lo).head<3>().cast<double>().array() / leaf_m).floor() + 1.0;
  const double limit = static_cast<double>(std::numeric_limits<int32_t>::max()) / 2.0;
  const double yz_cells = cells.y() * cells.z();
  const int slab_cells = static_cast<int>(std::max(1.0, std::floor(limit / yz_cells)));
  const int slabs = static_cast<int>(std::ceil(cells.x() / slab_cells));
  std::vector<Cloud::Ptr> parts(static_cast<size_t>(slabs));
  for (auto& part : parts) part = std::make_shared<Cloud>();
  for (const pcl::PointXYZRGB& point : *cloud) {
    const int cell = static_cast<int>(std::floor((point.x - lo.x()) / leaf_m));
    parts[static_cast<size_t>(std::min(slabs - 1, cell / slab_cells))]->push_back(point);
  }
  auto filtered = std::make_shared<Cloud>();
  pcl::VoxelGrid<pcl::PointXYZRGB> grid;
  const float leaf = static_cast<float>(leaf_m);
  grid.setLeafSize(leaf, leaf, leaf);
  for (const Cloud::Ptr& part : parts) {
    if (part->empty()) continue;
    Cloud kept;
    grid.setInputCloud(part);
    grid.filter(kept);
    *filtered += kept;
  }
  return filtered;
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
  auto cloud = std::make_shared<Cloud>();
  size_t refilter_at = kRefilterPoints;
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
        const Eigen::Vector3f world = world_from_cam * k.Unproject(u, v, z_mm * 1e-3).cast<float>();
        pcl::PointXYZRGB point;
        point.x = world.x();
        point.y = world.y();
        point.z = world.z();
        point.b = color_row[u][0];
        point.g = color_row[u][1];
        point.r = color_row[u][2];
        cloud->push_back(point);
        ++stats.back_projected_points;
      }
    }
    ++stats.keyframes;
    if (cloud->size() > refilter_at) {
      cloud = VoxelFilter(cloud, options.voxel_size_m);
      refilter_at = std::max(kRefilterPoints, 2 * cloud->size());
    }
  }
  cloud = VoxelFilter(cloud, options.voxel_size_m);
  if (options.remove_outliers && cloud->size() > static_cast<size_t>(options.outlier_neighbours)) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZRGB> removal;
    removal.setInputCloud(cloud);
    removal.setMeanK(options.outlier_neighbours);
    removal.setStddevMulThresh(options.outlier_stddev);
    auto kept = std::make_shared<Cloud>();
    removal.filter(*kept);
    cloud = kept;
  }
  SIGHTMAP_CHECK(!cloud->empty(), "no keyframe of model "
                                      << model.path() << " has depth within ["
                                      << options.min_depth_m << ", " << options.max_depth_m
                                      << "] m: there is no point cloud to export");
  cloud->width = static_cast<uint32_t>(cloud->size());
  cloud->height = 1;
  cloud->is_dense = true;
  // Open the file ourselves first: PCL reports failures on stderr, and the CLI promises one line.
  SIGHTMAP_CHECK(std::ofstream(path, std::ios::binary).is_open(),
                 "cannot write " << path << ": check that its folder exists and is writable");
  // No camera element in the header: CloudCompare and MeshLab read it, but it is not standard PLY.
  pcl::PLYWriter writer;
  const pcl::console::VERBOSITY_LEVEL verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  const int rc = writer.write(path, *cloud, /*binary=*/true, /*use_camera=*/false);
  pcl::console::setVerbosityLevel(verbosity);
  SIGHTMAP_CHECK(rc == 0, "cannot write " << path << ": is the disk full?");
  stats.written_points = static_cast<int64_t>(cloud->size());
  return stats;
}

std::vector<ColoredPoint> ReadPly(const std::string& path) {
  std::error_code ec;
  SIGHTMAP_CHECK(std::filesystem::is_regular_file(path, ec),
                 "cannot read " << path << ": no such file");
  Cloud cloud;
  pcl::PLYReader reader;
  const pcl::console::VERBOSITY_LEVEL verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  const int rc = reader.read(path, cloud);
  pcl::console::setVerbosityLevel(verbosity);
  SIGHTMAP_CHECK(rc == 0, "cannot read " << path << " as PLY: it is damaged or not a PLY file");
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

}  // namespace sightmap
