#include "slam/manhattan_frame.h"

#include <algorithm>
#include <cmath>

#include <Eigen/SVD>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"

namespace sightmap::slam {

std::vector<PlanePatch> PlanePatches(const cv::Mat& depth_mm, const Intrinsics& camera,
                                     const ManhattanOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 && depth_mm.cols == camera.width &&
                     depth_mm.rows == camera.height,
                 "depth must be 16-bit millimetres of the camera's size");
  const int step = options.grid_step_px;
  const int rows = depth_mm.rows / step;
  const int cols = depth_mm.cols / step;
  const double max_depth_mm = options.max_depth_m * 1000.0;
  std::vector<Eigen::Vector3d> points(static_cast<size_t>(rows) * cols);
  std::vector<bool> valid(points.size(), false);
  for (int r = 0; r < rows; ++r) {
    const int v = r * step + step / 2;
    const uint16_t* row = depth_mm.ptr<uint16_t>(v);
    for (int c = 0; c < cols; ++c) {
      const int u = c * step + step / 2;
      const double z_mm = row[u];
      if (z_mm <= 0.0 || z_mm > max_depth_mm) continue;
      points[static_cast<size_t>(r) * cols + c] = camera.Unproject(u, v, z_mm * 1e-3);
      valid[static_cast<size_t>(r) * cols + c] = true;
    }
  }
  const int k = options.normal_span_cells;
  std::vector<PlanePatch> patches;
  patches.reserve(points.size());
  const double min_incidence_cos = std::cos(DegToRad(options.max_incidence_deg));
  auto at = [&](int r, int c) { return static_cast<size_t>(r) * cols + c; };
  for (int r = k; r + k < rows; ++r) {
    for (int c = k; c + k < cols; ++c) {
      const size_t centre = at(r, c), left = at(r, c - k), right = at(r, c + k), up = at(r - k, c),
                   down = at(r + k, c);
      if (!(valid[centre] && valid[left] && valid[right] && valid[up] && valid[down])) continue;
      const Eigen::Vector3d along_u = points[right] - points[left];
      const Eigen::Vector3d along_v = points[down] - points[up];
      Eigen::Vector3d normal = along_u.cross(along_v);
      const double norm = normal.norm();
      if (!(norm > 0.0)) continue;
      normal /= norm;
      // The centre on the plane of its four neighbours: not an edge or a corner.
      const Eigen::Vector3d mean =
          0.25 * (points[left] + points[right] + points[up] + points[down]);
      const double span = 0.5 * (along_u.norm() + along_v.norm());
      if (std::abs((points[centre] - mean).dot(normal)) > options.max_planarity_error * span) {
        continue;
      }
      if (normal.dot(points[centre]) > 0.0) normal = -normal;
      // Seen edge-on, a plane's disparity steps are long and its normals lean towards the ray.
      if (-normal.dot(points[centre].normalized()) < min_incidence_cos) continue;
      patches.push_back({normal, points[centre]});
    }
  }
  return patches;
}

namespace {

// The mean of the normals within `max_angle` of the axis `axis` or of its opposite (flipped onto
// it), normalised; nullopt when fewer than `min_count`.
std::optional<Eigen::Vector3d> AxisMean(const std::vector<Eigen::Vector3d>& normals,
                                        const Eigen::Vector3d& axis, double max_angle,
                                        int min_count) {
  const double min_cos = std::cos(max_angle);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (const Eigen::Vector3d& normal : normals) {
    const double cos = normal.dot(axis);
    if (std::abs(cos) < min_cos) continue;
    sum += cos > 0.0 ? normal : Eigen::Vector3d(-normal);
    ++count;
  }
  if (count < min_count || !(sum.norm() > 0.0)) return std::nullopt;
  return sum.normalized();
}

// The heading (modulo 90 degrees, in [0, pi/2)) of the normals perpendicular to `up`, measured in
// the plane basis (east, north): the peak of their histogram, refined by the mean around it.
std::optional<double> WallHeading(const std::vector<Eigen::Vector3d>& normals,
                                  const Eigen::Vector3d& up, const Eigen::Vector3d& east,
                                  const Eigen::Vector3d& north, const ManhattanOptions& options,
                                  int min_count) {
  const double quarter = kPi / 2.0;
  const int bins = std::max(4, static_cast<int>(std::lround(90.0 / options.heading_bin_deg)));
  std::vector<double> headings;
  std::vector<int> histogram(bins, 0);
  const double max_sin = std::sin(DegToRad(options.assign_deg));
  for (const Eigen::Vector3d& normal : normals) {
    if (std::abs(normal.dot(up)) > max_sin) continue;
    double heading = std::fmod(std::atan2(normal.dot(north), normal.dot(east)), quarter);
    if (heading < 0.0) heading += quarter;
    headings.push_back(heading);
    ++histogram[std::min(bins - 1, static_cast<int>(heading / quarter * bins))];
  }
  if (static_cast<int>(headings.size()) < min_count) return std::nullopt;
  // The bin whose neighbourhood (the assignment angle either side, circular) holds the most.
  const int half_window =
      std::max(1, static_cast<int>(std::lround(options.assign_deg / (90.0 / bins))) / 2);
  int best_bin = 0, best_count = -1;
  for (int bin = 0; bin < bins; ++bin) {
    int count = 0;
    for (int offset = -half_window; offset <= half_window; ++offset) {
      count += histogram[((bin + offset) % bins + bins) % bins];
    }
    if (count > best_count) {
      best_count = count;
      best_bin = bin;
    }
  }
  if (best_count < min_count) return std::nullopt;
  // Circular mean (period 90 degrees) of the headings near the peak.
  const double peak = (best_bin + 0.5) * quarter / bins;
  double sin_sum = 0.0, cos_sum = 0.0;
  for (double heading : headings) {
    const double difference = std::remainder(heading - peak, quarter);
    if (std::abs(difference) > DegToRad(options.assign_deg)) continue;
    sin_sum += std::sin(4.0 * heading);
    cos_sum += std::cos(4.0 * heading);
  }
  double heading = std::atan2(sin_sum, cos_sum) / 4.0;
  if (heading < 0.0) heading += quarter;
  return heading;
}

// Kabsch refinement: each normal within the assignment angle of an axis (or its opposite) pulls
// that axis towards it. Fills the fit's rotation and support.
void RefineAxes(const std::vector<Eigen::Vector3d>& normals, const ManhattanOptions& options,
                ManhattanFit* fit) {
  const double min_cos = std::cos(DegToRad(options.assign_deg));
  for (int iteration = 0; iteration < 3; ++iteration) {
    Eigen::Matrix3d correlation = Eigen::Matrix3d::Zero();
    fit->support = {0, 0, 0};
    for (const Eigen::Vector3d& normal : normals) {
      const Eigen::Vector3d in_axes = fit->cam_from_manhattan.transpose() * normal;
      int axis = 0;
      in_axes.cwiseAbs().maxCoeff(&axis);
      const double cos = std::abs(in_axes[axis]);
      if (cos < min_cos) continue;
      Eigen::Vector3d target = Eigen::Vector3d::Zero();
      target[axis] = in_axes[axis] > 0.0 ? 1.0 : -1.0;
      correlation += normal * target.transpose();
      ++fit->support[axis];
    }
    const int assigned = fit->support[0] + fit->support[1] + fit->support[2];
    if (assigned == 0) return;
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(correlation,
                                                Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d sign = Eigen::Matrix3d::Identity();
    sign(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() > 0.0 ? 1.0 : -1.0;
    fit->cam_from_manhattan = svd.matrixU() * sign * svd.matrixV().transpose();
  }
}

}  // namespace

bool ManhattanOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (grid_step_px < 1) return fail("grid_step_px must be at least 1");
  if (normal_span_cells < 1) return fail("normal_span_cells must be at least 1");
  if (!(max_depth_m > 0.0)) return fail("max_depth_m must be positive");
  if (!(max_planarity_error > 0.0)) return fail("max_planarity_error must be positive");
  if (!(max_incidence_deg > 0.0 && max_incidence_deg <= 90.0)) {
    return fail("max_incidence_deg must be in (0, 90]");
  }
  if (!(assign_deg > 0.0 && assign_deg < 45.0)) return fail("assign_deg must be in (0, 45)");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0)) return fail("max_tilt_deg must be in (0, 90)");
  if (min_axis_normals < 3) return fail("min_axis_normals must be at least 3");
  if (!(heading_bin_deg > 0.0 && heading_bin_deg <= 10.0)) {
    return fail("heading_bin_deg must be in (0, 10]");
  }
  return true;
}

std::optional<ManhattanFit> FitManhattanFrame(const cv::Mat& depth_mm, const Intrinsics& camera,
                                              const ManhattanOptions& options) {
  return FitManhattanFrame(PlanePatches(depth_mm, camera, options), options);
}

std::optional<ManhattanFit> FitManhattanFrame(const std::vector<PlanePatch>& patches,
                                              const ManhattanOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::vector<Eigen::Vector3d> normals;
  normals.reserve(patches.size());
  for (const PlanePatch& patch : patches) normals.push_back(patch.normal);
  ManhattanFit fit;
  fit.normals = static_cast<int>(normals.size());
  const int min_count = options.min_axis_normals;
  const Eigen::Vector3d expected_up(0.0, -1.0, 0.0);  // the image's up

  // The vertical: floor and ceiling normals near the expected up, then those near their mean.
  Eigen::Vector3d up = expected_up;
  if (const auto floor =
          AxisMean(normals, expected_up, DegToRad(options.max_tilt_deg), min_count)) {
    if (const auto refined = AxisMean(normals, *floor, DegToRad(options.assign_deg), min_count)) {
      up = *refined;
      if (up.dot(expected_up) < 0.0) up = -up;
    }
  }
  // The walls' heading about it.
  const Eigen::Vector3d reference =
      std::abs(up.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d east = (reference - reference.dot(up) * up).normalized();
  const Eigen::Vector3d north = up.cross(east);
  const std::optional<double> heading = WallHeading(normals, up, east, north, options, min_count);
  if (!heading) return std::nullopt;
  const Eigen::Vector3d wall = std::cos(*heading) * east + std::sin(*heading) * north;
  fit.cam_from_manhattan.col(0) = wall;
  fit.cam_from_manhattan.col(1) = up.cross(wall);
  fit.cam_from_manhattan.col(2) = up;
  RefineAxes(normals, options, &fit);
  int axes = 0;
  for (int support : fit.support) axes += support >= min_count ? 1 : 0;
  if (axes < 2) return std::nullopt;
  return fit;
}

const std::vector<Eigen::Matrix3d>& ManhattanSymmetries() {
  static const std::vector<Eigen::Matrix3d> symmetries = [] {
    std::vector<Eigen::Matrix3d> all;
    const std::array<std::array<int, 3>, 6> permutations = {
        {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
    for (const auto& permutation : permutations) {
      for (int signs = 0; signs < 8; ++signs) {
        Eigen::Matrix3d matrix = Eigen::Matrix3d::Zero();
        for (int column = 0; column < 3; ++column) {
          matrix(permutation[column], column) = (signs >> column) & 1 ? -1.0 : 1.0;
        }
        if (matrix.determinant() > 0.0) all.push_back(matrix);
      }
    }
    return all;
  }();
  return symmetries;
}

std::pair<Eigen::Matrix3d, double> NearestManhattanRotation(
    const Eigen::Matrix3d& world_from_manhattan, const Eigen::Matrix3d& cam_from_manhattan,
    const Eigen::Matrix3d& world_from_cam_estimate) {
  std::pair<Eigen::Matrix3d, double> nearest{world_from_cam_estimate, kPi * 2.0};
  for (const Eigen::Matrix3d& symmetry : ManhattanSymmetries()) {
    const Eigen::Matrix3d candidate =
        world_from_manhattan * symmetry * cam_from_manhattan.transpose();
    const double angle = Eigen::AngleAxisd(candidate * world_from_cam_estimate.transpose()).angle();
    if (angle < nearest.second) nearest = {candidate, angle};
  }
  return nearest;
}

SIGHTMAP_OPTIONS_JSON(ManhattanOptions, grid_step_px, normal_span_cells, max_depth_m,
                      max_planarity_error, max_incidence_deg, assign_deg, max_tilt_deg,
                      min_axis_normals, heading_bin_deg)

}  // namespace sightmap::slam
