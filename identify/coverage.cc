#include "identify/coverage.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"

namespace sightmap::identify {
namespace {

// The floor plan shows the space within this of eye height, and this much around it [m].
constexpr double kPlanHalfHeightM = 0.6;
constexpr double kPlanMarginM = 1.0;

// A dense grid of cells over the keyframes' reach, in world axes: what their depth rays crossed and
// where they ended on a surface.
class SpaceGrid {
 public:
  SpaceGrid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double cell_m)
      : lo_(lo), cell_m_(cell_m) {
    for (int a = 0; a < 3; ++a) {
      size_[a] = std::max(1, static_cast<int>(std::ceil((hi[a] - lo[a]) / cell_m)));
    }
    cells_.assign(static_cast<size_t>(size_[0]) * size_[1] * size_[2], FloorPlan::kUnknown);
  }

  double cell_m() const { return cell_m_; }

  // The cell's state, kUnknown outside the grid.
  uint8_t At(const Eigen::Vector3d& world) const {
    const int64_t index = Index(world);
    return index < 0 ? static_cast<uint8_t>(FloorPlan::kUnknown)
                     : cells_[static_cast<size_t>(index)];
  }

  // Raises the cell's state to `state` (a surface is never turned back into free space).
  void Mark(const Eigen::Vector3d& world, uint8_t state) {
    const int64_t index = Index(world);
    if (index < 0) return;
    uint8_t& cell = cells_[static_cast<size_t>(index)];
    cell = std::max(cell, state);
  }

  // Every cell's centre and state, for the floor plan.
  template <typename Visit>
  void ForEach(Visit visit) const {
    for (int z = 0; z < size_[2]; ++z) {
      for (int y = 0; y < size_[1]; ++y) {
        for (int x = 0; x < size_[0]; ++x) {
          const uint8_t state = cells_[Offset(x, y, z)];
          if (state == FloorPlan::kUnknown) continue;
          visit(Eigen::Vector3d(lo_ + cell_m_ * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5)), state);
        }
      }
    }
  }

 private:
  size_t Offset(int x, int y, int z) const {
    return (static_cast<size_t>(z) * size_[1] + y) * size_[0] + x;
  }
  int64_t Index(const Eigen::Vector3d& world) const {
    int c[3];
    for (int a = 0; a < 3; ++a) {
      const double f = std::floor((world[a] - lo_[a]) / cell_m_);
      if (!(f >= 0.0 && f < size_[a])) return -1;
      c[a] = static_cast<int>(f);
    }
    return static_cast<int64_t>(Offset(c[0], c[1], c[2]));
  }

  Eigen::Vector3d lo_;
  double cell_m_;
  int size_[3] = {1, 1, 1};
  std::vector<uint8_t> cells_;
};

// The grid over every keyframe's reach; its cells grow when the building is too large for
// max_cells at the asked size.
SpaceGrid MakeGrid(const std::vector<store::KeyframeInfo>& keyframes,
                   const CoverageOptions& options) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const store::KeyframeInfo& keyframe : keyframes) {
    lo = lo.cwiseMin(keyframe.world_from_cam.translation());
    hi = hi.cwiseMax(keyframe.world_from_cam.translation());
  }
  if (keyframes.empty()) lo = hi = Eigen::Vector3d::Zero();
  lo.array() -= options.max_depth_m;
  hi.array() += options.max_depth_m;
  constexpr double kMaxCells = 64e6;  // 64 MB
  const double volume = (hi - lo).prod();
  const double cell_m = std::max(options.cell_m, std::cbrt(volume / kMaxCells));
  return SpaceGrid(lo, hi, cell_m);
}

// Marks the space the depth rays of one keyframe crossed, and the surfaces they ended on.
void Carve(const store::KeyframeInfo& keyframe, const cv::Mat& depth_mm,
           const CoverageOptions& options, SpaceGrid* grid) {
  const Intrinsics camera = depth_mm.cols == keyframe.intrinsics.width
                                ? keyframe.intrinsics
                                : keyframe.intrinsics.Scaled(depth_mm.cols, depth_mm.rows);
  const int step_px = std::max(
      1, options.free_space_pixel_step * depth_mm.cols / std::max(1, keyframe.intrinsics.width));
  const Eigen::Vector3d centre = keyframe.world_from_cam.translation();
  const double step_m = 0.5 * grid->cell_m();
  for (int v = step_px / 2; v < depth_mm.rows; v += step_px) {
    for (int u = step_px / 2; u < depth_mm.cols; u += step_px) {
      const double z = 1e-3 * depth_mm.at<uint16_t>(v, u);
      if (!(z > 0.0) || z > options.max_depth_m) continue;
      const Eigen::Vector3d surface = keyframe.world_from_cam * camera.Unproject(u, v, z);
      const Eigen::Vector3d ray = surface - centre;
      const double length = ray.norm();
      const Eigen::Vector3d direction = ray / length;
      for (double t = 0.0; t < length - options.free_space_margin_m; t += step_m) {
        grid->Mark(centre + t * direction, FloorPlan::kFree);
      }
      grid->Mark(surface, FloorPlan::kSurface);
    }
  }
}

// Bearing [deg, 0-360) of `offset` in the floor plane.
double BearingDeg(const Eigen::Vector3d& offset, const ModelCoverage& coverage) {
  return FloorBearingDeg(offset, coverage.floor_x, coverage.floor_y);
}

// Whether a person standing `distance_m` from the label towards `bearing_deg`, at eye height,
// would see the label: the standpoint and the line of sight (but its last label_clearance_m) lie
// in crossed space.
bool CanSeeFrom(const Eigen::Vector3d& label_centre, double bearing_deg, double distance_m,
                const ModelCoverage& coverage, const SpaceGrid& grid,
                const CoverageOptions& options) {
  const double bearing = DegToRad(bearing_deg);
  const Eigen::Vector3d on_floor = label_centre - label_centre.dot(coverage.up) * coverage.up;
  const Eigen::Vector3d standpoint =
      on_floor + coverage.eye_height_m * coverage.up +
      distance_m * (std::cos(bearing) * coverage.floor_x + std::sin(bearing) * coverage.floor_y);
  const Eigen::Vector3d sight = label_centre - standpoint;
  const double length = sight.norm();
  const double step_m = 0.5 * grid.cell_m();
  for (double t = 0.0; t < length - options.label_clearance_m; t += step_m) {
    if (grid.At(standpoint + (t / length) * sight) != FloorPlan::kFree) return false;
  }
  return true;
}

void FindOpenSectors(const SpaceGrid& grid, const CoverageOptions& options,
                     const ModelCoverage& coverage, LabelCoverage* label) {
  for (SectorCoverage& sector : label->sectors) {
    const double bearing = 0.5 * (sector.from_deg + sector.to_deg);
    for (int probe = 0; probe < options.probes_per_sector; ++probe) {
      const double distance =
          options.min_distance_m + (options.max_distance_m - options.min_distance_m) *
                                       (probe + 0.5) / options.probes_per_sector;
      if (CanSeeFrom(label->centre, bearing, distance, coverage, grid, options)) {
        sector.open_distances_m.push_back(distance);
      }
    }
    sector.open = !sector.open_distances_m.empty();
    // Someone stood there and saw it.
    sector.open = sector.open || sector.seen();
    label->open += sector.open ? 1 : 0;
    label->seen += sector.seen() ? 1 : 0;
  }
}

FloorPlan MakeFloorPlan(const SpaceGrid& grid, const ModelCoverage& coverage,
                        const std::vector<store::KeyframeInfo>& keyframes) {
  FloorPlan plan;
  plan.cell_m = grid.cell_m();
  const auto floor_of = [&coverage](const Eigen::Vector3d& world) {
    return Eigen::Vector2d(world.dot(coverage.floor_x), world.dot(coverage.floor_y));
  };
  // A slice around eye height: walls and furniture, not the floor and ceiling that lie under and
  // over everything.
  const auto in_slice = [&](const Eigen::Vector3d& centre) {
    return std::abs(centre.dot(coverage.up) - coverage.eye_height_m) <= kPlanHalfHeightM;
  };
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  const auto extend = [&lo, &hi](const Eigen::Vector2d& at) {
    lo = lo.cwiseMin(at);
    hi = hi.cwiseMax(at);
  };
  grid.ForEach([&](const Eigen::Vector3d& centre, uint8_t) {
    if (in_slice(centre)) extend(floor_of(centre));
  });
  for (const store::KeyframeInfo& keyframe : keyframes) {
    plan.keyframes.push_back(floor_of(keyframe.world_from_cam.translation()));
    extend(plan.keyframes.back());
  }
  for (const LabelCoverage& label : coverage.labels) extend(floor_of(label.centre));
  if (!(lo.x() <= hi.x())) return plan;
  plan.origin = lo - Eigen::Vector2d::Constant(kPlanMarginM);
  const Eigen::Vector2i size =
      ((hi - plan.origin).array() / plan.cell_m + kPlanMarginM / plan.cell_m).ceil().cast<int>();
  plan.cells = cv::Mat::zeros(size.y(), size.x(), CV_8UC1);
  grid.ForEach([&](const Eigen::Vector3d& centre, uint8_t state) {
    if (!in_slice(centre)) return;
    const Eigen::Vector2d at = (floor_of(centre) - plan.origin) / plan.cell_m;
    const int col = std::clamp(static_cast<int>(at.x()), 0, plan.cells.cols - 1);
    const int row = std::clamp(static_cast<int>(at.y()), 0, plan.cells.rows - 1);
    uint8_t& cell = plan.cells.at<uint8_t>(row, col);
    cell = std::max(cell, state);
  });
  return plan;
}

}  // namespace

bool CoverageOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (sectors < 4 || sectors > 360) return fail("sectors must be in [4, 360]");
  if (!(min_distance_m > 0.0) || !(max_distance_m > min_distance_m)) {
    return fail("the distance band needs 0 < min_distance_m < max_distance_m");
  }
  if (probes_per_sector < 1) return fail("probes_per_sector must be at least 1");
  if (!(cell_m >= 0.02 && cell_m <= 2.0)) return fail("cell_m must be in [0.02, 2] m");
  if (free_space_pixel_step < 1) return fail("free_space_pixel_step must be at least 1");
  if (!(free_space_margin_m >= 0.0) || !(max_depth_m > 0.0) || !(label_clearance_m >= 0.0)) {
    return fail("free_space_margin_m, label_clearance_m must be >= 0 and max_depth_m > 0");
  }
  return view.Check(error);
}

Eigen::Vector3d EstimateWorldUp(const std::vector<store::KeyframeInfo>& keyframes) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const store::KeyframeInfo& keyframe : keyframes) {
    sum -= keyframe.world_from_cam.linear().col(1);
  }
  return sum.norm() > 1e-6 ? Eigen::Vector3d(sum.normalized()) : Eigen::Vector3d::UnitZ();
}

ModelCoverage ComputeCoverage(const store::Model& model, const CoverageOptions& options,
                              const std::function<void(int, int)>& progress) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  const std::vector<store::LabelRecord> records = model.Labels();
  ModelCoverage coverage;
  coverage.up = EstimateWorldUp(keyframes);
  FloorAxes(coverage.up, &coverage.floor_x, &coverage.floor_y);
  for (const store::KeyframeInfo& keyframe : keyframes) {
    coverage.eye_height_m += keyframe.world_from_cam.translation().dot(coverage.up);
  }
  if (!keyframes.empty()) coverage.eye_height_m /= static_cast<double>(keyframes.size());

  const double sector_deg = 360.0 / options.sectors;
  for (const store::LabelRecord& record : records) {
    LabelCoverage label;
    label.id = record.id;
    label.name = record.name;
    label.type = record.type;
    label.centre = LabelCentre(record);
    for (int s = 0; s < options.sectors; ++s) {
      SectorCoverage sector;
      sector.from_deg = s * sector_deg;
      sector.to_deg = (s + 1) * sector_deg;
      label.sectors.push_back(sector);
    }
    coverage.labels.push_back(std::move(label));
  }

  SpaceGrid grid = MakeGrid(keyframes, options);
  for (size_t k = 0; k < keyframes.size(); ++k) {
    const store::KeyframeInfo& keyframe = keyframes[k];
    const cv::Mat depth = model.LoadDepth(keyframe.id);
    if (!depth.empty()) {
      Carve(keyframe, depth, options, &grid);
      for (const LabelInKeyframe& in_view :
           LabelsInKeyframe(keyframe, depth, records, options.view)) {
        const bool visible = std::any_of(in_view.points.begin(), in_view.points.end(),
                                         [](const LabelPointInKeyframe& p) { return !p.hidden; });
        if (!visible) continue;
        LabelCoverage& label = coverage.labels[static_cast<size_t>(in_view.label - records.data())];
        ++label.keyframes;
        const Eigen::Vector3d offset = keyframe.world_from_cam.translation() - label.centre;
        const double distance = offset.norm();
        if (distance < options.min_distance_m || distance > options.max_distance_m) continue;
        const int s = std::min(options.sectors - 1,
                               static_cast<int>(BearingDeg(offset, coverage) / sector_deg));
        SectorCoverage& sector = label.sectors[static_cast<size_t>(s)];
        sector.nearest_m = sector.keyframes == 0 ? distance : std::min(sector.nearest_m, distance);
        sector.farthest_m = std::max(sector.farthest_m, distance);
        ++sector.keyframes;
      }
    }
    if (progress) progress(static_cast<int>(k + 1), static_cast<int>(keyframes.size()));
  }
  for (LabelCoverage& label : coverage.labels) {
    FindOpenSectors(grid, options, coverage, &label);
    coverage.open += label.open;
    coverage.seen += label.seen;
  }
  coverage.floor = MakeFloorPlan(grid, coverage, keyframes);
  return coverage;
}

nlohmann::json CoverageToJson(const ModelCoverage& coverage) {
  nlohmann::json labels = nlohmann::json::array();
  for (const LabelCoverage& label : coverage.labels) {
    nlohmann::json sectors = nlohmann::json::array();
    for (const SectorCoverage& sector : label.sectors) {
      sectors.push_back({{"from_deg", sector.from_deg},
                         {"to_deg", sector.to_deg},
                         {"open", sector.open},
                         {"seen", sector.seen()},
                         {"keyframes", sector.keyframes},
                         {"nearest_m", sector.nearest_m},
                         {"farthest_m", sector.farthest_m},
                         {"open_distances_m", sector.open_distances_m}});
    }
    labels.push_back({{"id", label.id.value()},
                      {"name", label.name},
                      {"type", label.type},
                      {"centre", {label.centre.x(), label.centre.y(), label.centre.z()}},
                      {"share", label.share()},
                      {"open_sectors", label.open},
                      {"seen_sectors", label.seen},
                      {"keyframes", label.keyframes},
                      {"sectors", sectors}});
  }
  return {{"share", coverage.share()},
          {"open_sectors", coverage.open},
          {"seen_sectors", coverage.seen},
          {"up", {coverage.up.x(), coverage.up.y(), coverage.up.z()}},
          {"eye_height_m", coverage.eye_height_m},
          {"labels", labels}};
}

cv::Mat DrawCoverage(const ModelCoverage& coverage, int max_side_px) {
  SIGHTMAP_CHECK(max_side_px >= 64, "a coverage plan needs at least 64 pixels a side");
  const FloorPlan& plan = coverage.floor;
  if (plan.cells.empty())
    return cv::Mat(max_side_px / 2, max_side_px, CV_8UC3, cv::Scalar::all(255));
  const double px_per_cell =
      static_cast<double>(max_side_px) / std::max(plan.cells.cols, plan.cells.rows);
  const cv::Size size(static_cast<int>(std::lround(plan.cells.cols * px_per_cell)),
                      static_cast<int>(std::lround(plan.cells.rows * px_per_cell)));
  cv::Mat shades(plan.cells.size(), CV_8UC1);
  for (int r = 0; r < plan.cells.rows; ++r) {
    for (int c = 0; c < plan.cells.cols; ++c) {
      const uint8_t cell = plan.cells.at<uint8_t>(r, c);
      shades.at<uint8_t>(r, c) = cell == FloorPlan::kSurface ? 70
                                 : cell == FloorPlan::kFree  ? 228
                                                             : 255;
    }
  }
  // Drawn as maps are, the floor's second axis up the image.
  cv::flip(shades, shades, 0);
  cv::Mat grey;
  cv::resize(shades, grey, size, 0.0, 0.0, cv::INTER_NEAREST);
  cv::Mat image;
  cv::cvtColor(grey, image, cv::COLOR_GRAY2BGR);
  const double px_per_m = px_per_cell / plan.cell_m;
  const auto pixel_of = [&](const Eigen::Vector2d& floor) {
    const Eigen::Vector2d at = (floor - plan.origin) * px_per_m;
    return cv::Point(static_cast<int>(std::lround(at.x())),
                     static_cast<int>(std::lround(size.height - at.y())));
  };
  for (const Eigen::Vector2d& keyframe : plan.keyframes) {
    cv::circle(image, pixel_of(keyframe), 1, cv::Scalar(200, 120, 30), cv::FILLED);
  }
  const int radius = std::max(10, max_side_px / 40);
  for (const LabelCoverage& label : coverage.labels) {
    const cv::Point at = pixel_of(
        Eigen::Vector2d(label.centre.dot(coverage.floor_x), label.centre.dot(coverage.floor_y)));
    for (const SectorCoverage& sector : label.sectors) {
      if (!sector.open) continue;
      const cv::Scalar colour = sector.seen() ? cv::Scalar(60, 170, 40) : cv::Scalar(40, 40, 220);
      // OpenCV's angles turn clockwise on screen; bearings turn counter-clockwise on the plan.
      cv::ellipse(image, at, cv::Size(radius, radius), 0.0, -sector.to_deg, -sector.from_deg,
                  colour, cv::FILLED);
    }
    cv::circle(image, at, radius, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    cv::circle(image, at, 2, cv::Scalar(0, 0, 0), cv::FILLED);
    // The name to the right of the ring, or to its left where the plan ends.
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label.name, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &baseline);
    const bool left = at.x + radius + 3 + text.width > image.cols;
    const cv::Point origin =
        at + cv::Point(left ? -radius - 3 - text.width : radius + 3, text.height / 2);
    cv::putText(image, label.name, origin, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(20, 20, 20), 1,
                cv::LINE_AA);
  }
  return image;
}

SIGHTMAP_OPTIONS_JSON(CoverageOptions, sectors, min_distance_m, max_distance_m, probes_per_sector,
                      cell_m, free_space_pixel_step, free_space_margin_m, max_depth_m,
                      label_clearance_m, view)

SIGHTMAP_OPTIONS_JSON(ViewSeenOptions, max_angle_deg, max_distance_ratio)

bool ViewSeenOptions::Check(std::string* error) const {
  if (!(max_angle_deg > 0.0 && max_angle_deg <= 180.0)) {
    *error = "max_angle_deg must be in (0, 180]";
    return false;
  }
  if (!(max_distance_ratio >= 1.0)) {
    *error = "max_distance_ratio must be >= 1";
    return false;
  }
  return true;
}

namespace {

// The cosine of the angle between the photo's and the keyframe's lines of sight to the point,
// when the keyframe has the point in its image within a factor max_distance_ratio of the photo's
// distance.
std::optional<double> ViewCosine(const Eigen::Vector3d& photo_ray, double photo_distance,
                                 const Eigen::Vector3d& point_world,
                                 const store::KeyframeInfo& keyframe, double max_distance_ratio) {
  const Eigen::Vector3d ray = point_world - keyframe.world_from_cam.translation();
  const double distance = ray.norm();
  if (distance < photo_distance / max_distance_ratio ||
      distance > photo_distance * max_distance_ratio) {
    return std::nullopt;
  }
  const Eigen::Vector3d in_cam = keyframe.world_from_cam.inverse() * point_world;
  if (in_cam.z() <= 0.0) return std::nullopt;
  const Eigen::Vector2d pixel = keyframe.intrinsics.Project(in_cam);
  if (pixel.x() < 0.0 || pixel.y() < 0.0 || pixel.x() >= keyframe.intrinsics.width ||
      pixel.y() >= keyframe.intrinsics.height) {
    return std::nullopt;
  }
  return ray.dot(photo_ray) / (distance * photo_distance);
}

}  // namespace

std::optional<double> NearestViewAngleDeg(const Eigen::Isometry3d& world_from_photo,
                                          const Eigen::Vector3d& point_world,
                                          const std::vector<store::KeyframeInfo>& keyframes,
                                          double max_distance_ratio) {
  const Eigen::Vector3d photo_ray = point_world - world_from_photo.translation();
  const double photo_distance = photo_ray.norm();
  if (photo_distance < 1e-6) return std::nullopt;
  std::optional<double> best_cos;
  for (const store::KeyframeInfo& keyframe : keyframes) {
    const std::optional<double> cos =
        ViewCosine(photo_ray, photo_distance, point_world, keyframe, max_distance_ratio);
    if (cos && (!best_cos || *cos > *best_cos)) best_cos = cos;
  }
  if (!best_cos) return std::nullopt;
  return RadToDeg(std::acos(std::clamp(*best_cos, -1.0, 1.0)));
}

std::vector<size_t> KeyframesSeeingView(const Eigen::Isometry3d& world_from_photo,
                                        const Eigen::Vector3d& point_world,
                                        const std::vector<store::KeyframeInfo>& keyframes,
                                        const ViewSeenOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const Eigen::Vector3d photo_ray = point_world - world_from_photo.translation();
  const double photo_distance = photo_ray.norm();
  std::vector<size_t> seeing;
  if (photo_distance < 1e-6) return seeing;
  const double min_cos = std::cos(DegToRad(options.max_angle_deg));
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const std::optional<double> cos = ViewCosine(photo_ray, photo_distance, point_world,
                                                 keyframes[i], options.max_distance_ratio);
    if (cos && *cos >= min_cos) seeing.push_back(i);
  }
  return seeing;
}

bool ViewWasSeen(const Eigen::Isometry3d& world_from_photo, const Eigen::Vector3d& point_world,
                 const std::vector<store::KeyframeInfo>& keyframes,
                 const ViewSeenOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  return IsSeenAngle(
      NearestViewAngleDeg(world_from_photo, point_world, keyframes, options.max_distance_ratio),
      options);
}

bool IsSeenAngle(const std::optional<double>& nearest_angle_deg, const ViewSeenOptions& options) {
  return nearest_angle_deg && *nearest_angle_deg <= options.max_angle_deg;
}

}  // namespace sightmap::identify
