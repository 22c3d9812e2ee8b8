#include "synthesis/view_synthesis.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "core/timing.h"

namespace sightmap::synthesis {
namespace {

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double c = a.normalized().dot(b.normalized());
  return RadToDeg(std::acos(std::clamp(c, -1.0, 1.0)));
}

// The keyframe's depth at `pixel` [m], 0 when none or outside.
double DepthAt(const cv::Mat& depth_mm, const Eigen::Vector2d& pixel) {
  const int u = static_cast<int>(std::lround(pixel.x()));
  const int v = static_cast<int>(std::lround(pixel.y()));
  if (u < 0 || v < 0 || u >= depth_mm.cols || v >= depth_mm.rows) return 0.0;
  return depth_mm.at<uint16_t>(v, u) / 1000.0;
}

// Whether a person at `eye` would look up or down at `target` more steeply than max_pitch_deg.
bool TooSteep(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up,
              const ViewSynthesisOptions& options) {
  const double sine = std::abs((target - eye).normalized().dot(up));
  return RadToDeg(std::asin(std::min(1.0, sine))) > options.max_pitch_deg;
}

// A standpoint posed `world_from_cam`, looking at `label`.
Standpoint LookingAt(const identify::LabelCoverage& label, const Eigen::Isometry3d& world_from_cam,
                     double bearing_deg, double distance_m) {
  Standpoint standpoint;
  standpoint.label = label.id;
  standpoint.label_name = label.name;
  standpoint.target = label.centre;
  standpoint.world_from_cam = world_from_cam;
  standpoint.bearing_deg = bearing_deg;
  standpoint.distance_m = distance_m;
  return standpoint;
}

// The floor plan's cell under floor coordinates `at`, kUnknown outside the plan.
uint8_t PlanCell(const identify::FloorPlan& plan, const Eigen::Vector2d& at) {
  const Eigen::Vector2d cell = (at - plan.origin) / plan.cell_m;
  const int col = static_cast<int>(std::floor(cell.x()));
  const int row = static_cast<int>(std::floor(cell.y()));
  if (plan.cells.empty() || col < 0 || row < 0 || col >= plan.cells.cols ||
      row >= plan.cells.rows) {
    return identify::FloorPlan::kUnknown;
  }
  return plan.cells.at<uint8_t>(row, col);
}

// Whether a person fits at `at`: its cell crossed by the keyframes' depth, and no surface within
// `clearance_m` of it.
bool PersonFits(const identify::FloorPlan& plan, const Eigen::Vector2d& at, double clearance_m) {
  if (PlanCell(plan, at) != identify::FloorPlan::kFree) return false;
  const double step = 0.5 * plan.cell_m;
  for (double dy = -clearance_m; dy <= clearance_m; dy += step) {
    for (double dx = -clearance_m; dx <= clearance_m; dx += step) {
      if (dx * dx + dy * dy > clearance_m * clearance_m) continue;
      if (PlanCell(plan, at + Eigen::Vector2d(dx, dy)) == identify::FloorPlan::kSurface) {
        return false;
      }
    }
  }
  return true;
}

// Whether the floor plan's cells from `from` towards `to` are free, but the last `clearance_m`
// (the appliance's own surface and the wall it hangs on).
bool InPlainSight(const identify::FloorPlan& plan, const Eigen::Vector2d& from,
                  const Eigen::Vector2d& to, double clearance_m) {
  const Eigen::Vector2d sight = to - from;
  const double length = sight.norm();
  const double step = 0.5 * plan.cell_m;
  for (double t = 0.0; t < length - clearance_m; t += step) {
    if (PlanCell(plan, from + (t / length) * sight) != identify::FloorPlan::kFree) return false;
  }
  return true;
}

}  // namespace

bool ViewSynthesisOptions::Check(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  std::string why;
  if (!coverage.Check(&why)) return fail("coverage: " + why);
  if (!slam::CheckOrbFeatures(features, &why)) return fail("features: " + why);
  if (!(max_pitch_deg > 0.0 && max_pitch_deg <= 90.0)) {
    return fail("max_pitch_deg must be in (0, 90]");
  }
  if (!(grid_step_m >= 0.0)) return fail("grid_step_m must be >= 0 (0: no grid)");
  if (grid_step_m > 0.0 && grid_step_m < 0.1) return fail("grid_step_m must be 0 or >= 0.1");
  if (!(grid_clearance_m >= 0.0)) return fail("grid_clearance_m must be >= 0");
  if (!grid_seen.Check(&why)) return fail("grid_seen: " + why);
  if (max_sources < 1) return fail("max_sources must be >= 1");
  if (!(max_source_angle_deg > 0.0 && max_source_angle_deg <= 180.0)) {
    return fail("max_source_angle_deg must be in (0, 180]");
  }
  if (mesh_step_px < 1) return fail("mesh_step_px must be >= 1");
  if (!(max_edge_depth_ratio > 0.0)) return fail("max_edge_depth_ratio must be > 0");
  if (!(max_depth_m > features.min_depth_m)) {
    return fail("max_depth_m must be greater than features.min_depth_m");
  }
  if (!(composite_depth_ratio >= 0.0)) return fail("composite_depth_ratio must be >= 0");
  if (!(min_drawn_share >= 0.0 && min_drawn_share <= 1.0)) {
    return fail("min_drawn_share must be in [0, 1]");
  }
  if (min_features < 1) return fail("min_features must be >= 1");
  return true;
}

std::vector<Standpoint> PlanStandpoints(const identify::ModelCoverage& coverage,
                                        const ViewSynthesisOptions& options) {
  std::vector<Standpoint> standpoints;
  for (const identify::LabelCoverage& label : coverage.labels) {
    for (const identify::SectorCoverage& sector : label.sectors) {
      if (options.missing_sectors_only && sector.seen()) continue;
      const double bearing_deg = 0.5 * (sector.from_deg + sector.to_deg);
      const double bearing = DegToRad(bearing_deg);
      const Eigen::Vector3d on_floor = label.centre - label.centre.dot(coverage.up) * coverage.up;
      for (const double distance : sector.open_distances_m) {
        const Eigen::Vector3d eye = on_floor + coverage.eye_height_m * coverage.up +
                                    distance * (std::cos(bearing) * coverage.floor_x +
                                                std::sin(bearing) * coverage.floor_y);
        if (TooSteep(eye, label.centre, coverage.up, options)) continue;
        standpoints.push_back(
            LookingAt(label, LookAt(eye, label.centre, coverage.up), bearing_deg, distance));
      }
    }
  }
  return standpoints;
}

std::vector<Standpoint> PlanGridStandpoints(const identify::ModelCoverage& coverage,
                                            const std::vector<store::KeyframeInfo>& keyframes,
                                            const ViewSynthesisOptions& options) {
  std::vector<Standpoint> standpoints;
  const identify::FloorPlan& plan = coverage.floor;
  if (!(options.grid_step_m > 0.0) || plan.cells.empty()) return standpoints;
  const double step = options.grid_step_m;
  const Eigen::Vector2d lo = plan.origin;
  const Eigen::Vector2d hi =
      plan.origin + plan.cell_m * Eigen::Vector2d(plan.cells.cols, plan.cells.rows);
  const auto floor_of = [&coverage](const Eigen::Vector3d& world) {
    return Eigen::Vector2d(world.dot(coverage.floor_x), world.dot(coverage.floor_y));
  };
  const identify::CoverageOptions& band = options.coverage;
  // Grid points on multiples of the step, so a model's grid does not move with its plan's extent.
  for (double y = std::ceil(lo.y() / step) * step; y < hi.y(); y += step) {
    for (double x = std::ceil(lo.x() / step) * step; x < hi.x(); x += step) {
      const Eigen::Vector2d at(x, y);
      if (!PersonFits(plan, at, options.grid_clearance_m)) continue;
      const Eigen::Vector3d eye =
          x * coverage.floor_x + y * coverage.floor_y + coverage.eye_height_m * coverage.up;
      for (const identify::LabelCoverage& label : coverage.labels) {
        const Eigen::Vector2d label_at = floor_of(label.centre);
        const double distance = (label_at - at).norm();
        if (distance < band.min_distance_m || distance > band.max_distance_m) continue;
        if (TooSteep(eye, label.centre, coverage.up, options)) continue;
        if (!InPlainSight(plan, at, label_at, band.label_clearance_m)) continue;
        const Eigen::Isometry3d world_from_cam = LookAt(eye, label.centre, coverage.up);
        if (identify::ViewWasSeen(world_from_cam, label.centre, keyframes, options.grid_seen)) {
          continue;
        }
        standpoints.push_back(LookingAt(
            label, world_from_cam,
            FloorBearingDeg(eye - label.centre, coverage.floor_x, coverage.floor_y), distance));
      }
    }
  }
  return standpoints;
}

render::TriangleMesh KeyframeMesh(const cv::Mat& depth_mm, const Intrinsics& intrinsics,
                                  const Eigen::Isometry3d& world_from_cam, int texture,
                                  const ViewSynthesisOptions& options) {
  SIGHTMAP_CHECK(depth_mm.type() == CV_16UC1 && depth_mm.cols == intrinsics.width &&
                     depth_mm.rows == intrinsics.height,
                 "a keyframe mesh needs 16-bit depth of its intrinsics' size");
  const int step = options.mesh_step_px;
  const int cols = (depth_mm.cols - 1) / step + 1;
  const int rows = (depth_mm.rows - 1) / step + 1;
  const double min_z = options.features.min_depth_m;
  // Grid vertices: world point and depth (0 = none).
  std::vector<Eigen::Vector3f> world(static_cast<size_t>(cols * rows));
  std::vector<float> z(world.size(), 0.0f);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int u = c * step;
      const int v = r * step;
      const double depth = depth_mm.at<uint16_t>(v, u) / 1000.0;
      if (depth < min_z || depth > options.max_depth_m) continue;
      const size_t i = static_cast<size_t>(r * cols + c);
      z[i] = static_cast<float>(depth);
      world[i] = (world_from_cam * intrinsics.Unproject(u, v, depth)).cast<float>();
    }
  }
  render::TriangleMesh mesh;
  mesh.material.texture = texture;
  mesh.material.unlit = true;
  mesh.material.color_rgb = Eigen::Vector3f(1, 1, 1);
  const Eigen::Vector3f normal = (-world_from_cam.linear().col(2)).cast<float>();
  const auto uv = [&](int c, int r) {
    return Eigen::Vector2f((c * step + 0.5f) / depth_mm.cols, (r * step + 0.5f) / depth_mm.rows);
  };
  const auto add = [&](int c, int r) {
    mesh.positions.push_back(world[static_cast<size_t>(r * cols + c)]);
    mesh.normals.push_back(normal);
    mesh.uvs.push_back(uv(c, r));
  };
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < cols; ++c) {
      const float corners[4] = {z[static_cast<size_t>(r * cols + c)],
                                z[static_cast<size_t>(r * cols + c + 1)],
                                z[static_cast<size_t>((r + 1) * cols + c)],
                                z[static_cast<size_t>((r + 1) * cols + c + 1)]};
      const float lo = *std::min_element(corners, corners + 4);
      const float hi = *std::max_element(corners, corners + 4);
      if (lo <= 0.0f || hi - lo > options.max_edge_depth_ratio * lo) continue;
      add(c, r);
      add(c, r + 1);
      add(c + 1, r);
      add(c + 1, r);
      add(c, r + 1);
      add(c + 1, r + 1);
    }
  }
  return mesh;
}

Composite CompositeLayers(const std::vector<render::RenderedView>& layers, double depth_ratio) {
  SIGHTMAP_CHECK(!layers.empty(), "nothing to composite");
  const cv::Size size = layers.front().depth.size();
  for (const render::RenderedView& layer : layers) {
    SIGHTMAP_CHECK(layer.depth.size() == size && layer.color.size() == size &&
                       layer.depth.type() == CV_32F && layer.color.type() == CV_8UC3,
                   "composited layers must be renders of one size");
  }
  Composite out;
  out.color = cv::Mat::zeros(size, CV_8UC3);
  out.depth_m = cv::Mat::zeros(size, CV_32F);
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      float nearest = std::numeric_limits<float>::infinity();
      for (const render::RenderedView& layer : layers) {
        const float d = layer.depth.at<float>(v, u);
        if (d > 0.0f) nearest = std::min(nearest, d);
      }
      if (!std::isfinite(nearest)) continue;
      const float limit = nearest * (1.0f + static_cast<float>(depth_ratio));
      for (const render::RenderedView& layer : layers) {
        const float d = layer.depth.at<float>(v, u);
        if (d > 0.0f && d <= limit) {
          out.color.at<cv::Vec3b>(v, u) = layer.color.at<cv::Vec3b>(v, u);
          out.depth_m.at<float>(v, u) = d;
          ++out.drawn_pixels;
          break;
        }
      }
    }
  }
  return out;
}

Features KeepFeaturesOnDrawnPixels(const Features& features, const cv::Mat& drawn) {
  SIGHTMAP_CHECK(drawn.type() == CV_8UC1, "the drawn mask must be 8-bit, one channel");
  // Distance of each drawn pixel to the nearest undrawn one (image borders count as drawn: ORB
  // keeps its patches inside the image itself).
  cv::Mat binary = drawn != 0;
  cv::Mat distance;
  cv::distanceTransform(binary, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  Features kept;
  std::vector<int> rows;
  for (size_t i = 0; i < features.size(); ++i) {
    const cv::KeyPoint& kp = features.keypoints[i];
    const int u = std::clamp(static_cast<int>(std::lround(kp.pt.x)), 0, drawn.cols - 1);
    const int v = std::clamp(static_cast<int>(std::lround(kp.pt.y)), 0, drawn.rows - 1);
    if (distance.at<float>(v, u) < 0.5f * kp.size + 1.0f) continue;
    rows.push_back(static_cast<int>(i));
    kept.keypoints.push_back(kp);
    if (!features.points_cam.empty()) {
      kept.points_cam.push_back(features.points_cam[i]);
      kept.has_point.push_back(features.has_point[i]);
    }
  }
  if (!features.descriptors.empty()) {
    kept.descriptors.create(static_cast<int>(rows.size()), features.descriptors.cols,
                            features.descriptors.type());
    for (size_t r = 0; r < rows.size(); ++r) {
      features.descriptors.row(rows[r]).copyTo(kept.descriptors.row(static_cast<int>(r)));
    }
  }
  return kept;
}

struct ViewSynthesizer::Impl {
  const store::Model& model;
  ViewSynthesisOptions options;
  std::vector<store::KeyframeInfo> keyframes;
  Intrinsics intrinsics;  // of the rendered views: the first keyframe's
  render::MeshRenderer renderer;

  Impl(const store::Model& m, const ViewSynthesisOptions& o)
      : model(m), options(o), keyframes(m.Keyframes()), renderer(RendererOptions()) {}

  // A keyframe to draw, with the depth image read to choose it.
  struct Source {
    const store::KeyframeInfo* info;
    cv::Mat depth_mm;
  };
  // The keyframes that saw `target` unhidden, best first (ViewSynthesizer::ChooseSources).
  std::vector<Source> ChooseSources(const Eigen::Isometry3d& world_from_cam,
                                    const Eigen::Vector3d& target, KeyframeId exclude) const;

  static render::RenderOptions RendererOptions() {
    render::RenderOptions options;
    options.near_m = 0.1;
    options.far_m = 20.0;
    options.lights.clear();
    return options;
  }
};

ViewSynthesizer::ViewSynthesizer(const store::Model& model, const ViewSynthesisOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_ = std::make_unique<Impl>(model, options);
  SIGHTMAP_CHECK(!impl_->keyframes.empty(), "the model " << model.path()
                                                         << " has no keyframes to render views "
                                                            "from: map a building into it first");
  impl_->intrinsics = impl_->keyframes.front().intrinsics;
}

ViewSynthesizer::~ViewSynthesizer() = default;

std::vector<ViewSynthesizer::Impl::Source> ViewSynthesizer::Impl::ChooseSources(
    const Eigen::Isometry3d& world_from_cam, const Eigen::Vector3d& target,
    KeyframeId exclude) const {
  const Eigen::Vector3d view_sight = target - world_from_cam.translation();
  // Candidates by the angle of their line of sight to the target, before any image is read.
  std::vector<std::pair<double, size_t>> ranked;
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const store::KeyframeInfo& info = keyframes[i];
    if (info.id == exclude) continue;
    const Eigen::Vector3d in_cam = info.world_from_cam.inverse() * target;
    if (in_cam.z() < options.features.min_depth_m || in_cam.z() > options.max_depth_m) continue;
    const Eigen::Vector2d pixel = info.intrinsics.Project(in_cam);
    if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() > info.intrinsics.width - 1 ||
        pixel.y() > info.intrinsics.height - 1) {
      continue;
    }
    const double angle = AngleDeg(target - info.world_from_cam.translation(), view_sight);
    if (angle > options.max_source_angle_deg) continue;
    ranked.emplace_back(angle, i);
  }
  std::sort(ranked.begin(), ranked.end());
  // Then not hidden: the keyframe's depth at the target is not much nearer than the target.
  std::vector<Source> sources;
  for (const auto& [angle, i] : ranked) {
    if (static_cast<int>(sources.size()) >= options.max_sources) break;
    const store::KeyframeInfo& info = keyframes[i];
    if (info.depth_bytes == 0) continue;
    const Eigen::Vector3d in_cam = info.world_from_cam.inverse() * target;
    cv::Mat depth_mm = model.LoadDepth(info.id);
    const double depth = DepthAt(depth_mm, info.intrinsics.Project(in_cam));
    const double margin = options.coverage.view.depth_margin_m +
                          options.coverage.view.depth_margin_ratio * in_cam.z();
    if (depth > 0.0 && depth < in_cam.z() - margin) continue;
    sources.push_back({&info, std::move(depth_mm)});
  }
  return sources;
}

std::vector<KeyframeId> ViewSynthesizer::ChooseSources(const Eigen::Isometry3d& world_from_cam,
                                                       const Eigen::Vector3d& target,
                                                       KeyframeId exclude) const {
  std::vector<KeyframeId> ids;
  for (const Impl::Source& source : impl_->ChooseSources(world_from_cam, target, exclude)) {
    ids.push_back(source.info->id);
  }
  return ids;
}

ViewSynthesizer::Result ViewSynthesizer::Synthesize(const Eigen::Isometry3d& world_from_cam,
                                                    const Eigen::Vector3d& target,
                                                    KeyframeId exclude) const {
  const ViewSynthesisOptions& options = impl_->options;
  Result result;
  const std::vector<Impl::Source> sources = impl_->ChooseSources(world_from_cam, target, exclude);
  result.sources = static_cast<int>(sources.size());
  if (sources.empty()) {
    result.refusal = "no keyframe saw the target unhidden from within " +
                     std::to_string(static_cast<int>(options.max_source_angle_deg)) +
                     " degrees of this view";
    return result;
  }
  render::MeshRenderer& renderer = impl_->renderer;
  const Intrinsics& intrinsics = impl_->intrinsics;
  std::vector<render::RenderedView> layers;
  for (const Impl::Source& source : sources) {
    const store::KeyframeInfo& info = *source.info;
    renderer.ClearTextures();
    const int texture = renderer.AddTexture(impl_->model.LoadColor(info.id));
    renderer.AddMesh(
        KeyframeMesh(source.depth_mm, info.intrinsics, info.world_from_cam, texture, options));
    layers.push_back(renderer.Render(intrinsics, world_from_cam));
  }
  renderer.ClearTextures();
  const Composite composite = CompositeLayers(layers, options.composite_depth_ratio);
  result.drawn_share =
      static_cast<double>(composite.drawn_pixels) / (intrinsics.width * intrinsics.height);
  if (result.drawn_share < options.min_drawn_share) {
    std::ostringstream why;
    why << "the keyframes cover " << std::lround(100 * result.drawn_share)
        << "% of the view (at least " << std::lround(100 * options.min_drawn_share) << "% needed)";
    result.refusal = why.str();
    return result;
  }
  cv::Mat depth_mm;
  composite.depth_m.convertTo(depth_mm, CV_16U, 1000.0);
  const Features all =
      slam::ExtractFeatures(composite.color, depth_mm, intrinsics, options.features);
  Features features = KeepFeaturesOnDrawnPixels(all, depth_mm > 0);
  result.features = static_cast<int>(features.NumPoints());
  if (result.features < options.min_features) {
    result.refusal = "only " + std::to_string(result.features) +
                     " features with depth on the drawn part (at least " +
                     std::to_string(options.min_features) + " needed)";
    return result;
  }
  store::SyntheticViewRecord view;
  view.source = sources.front().info->id;
  view.source_from_cam = sources.front().info->world_from_cam.inverse() * world_from_cam;
  view.world_from_cam = world_from_cam;
  view.intrinsics = intrinsics;
  view.color = composite.color;
  view.features = std::move(features);
  result.view = std::move(view);
  return result;
}

nlohmann::json ToJson(const SynthesisReport& report) {
  return {{"labels", report.labels},
          {"standpoints", report.standpoints},
          {"grid_standpoints", report.grid_standpoints},
          {"written", report.written},
          {"refused", report.refused},
          {"deleted", report.deleted},
          {"bytes", report.bytes},
          {"seconds", report.seconds}};
}

SynthesisReport SynthesizeViews(store::Model& model, const ViewSynthesisOptions& options,
                                const std::function<void(int, int)>& progress) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  SIGHTMAP_CHECK(model.Summary().labels > 0,
                 "the model " << model.path()
                              << " has no labels: views are rendered around labelled appliances, "
                                 "so label them first ('sightmap label')");
  const identify::ModelCoverage coverage = identify::ComputeCoverage(model, options.coverage);
  std::vector<Standpoint> standpoints = PlanStandpoints(coverage, options);
  const std::vector<Standpoint> on_grid = PlanGridStandpoints(coverage, model.Keyframes(), options);
  standpoints.insert(standpoints.end(), on_grid.begin(), on_grid.end());
  ViewSynthesizer synthesizer(model, options);
  SynthesisReport report;
  report.labels = static_cast<int>(coverage.labels.size());
  report.standpoints = static_cast<int>(standpoints.size());
  report.grid_standpoints = static_cast<int>(on_grid.size());
  // The previous run's views stay until this run's are written: a run killed half-way leaves
  // both, and the next run replaces both. A new view's id exceeds every stored one (SQLite row
  // ids), so the old views are those before the first new one.
  SyntheticViewId first_written;
  for (size_t i = 0; i < standpoints.size(); ++i) {
    const Standpoint& standpoint = standpoints[i];
    ViewSynthesizer::Result result =
        synthesizer.Synthesize(standpoint.world_from_cam, standpoint.target);
    if (result.view) {
      result.view->label = standpoint.label;
      const SyntheticViewId id = model.AddSyntheticView(*result.view);
      if (!first_written.valid()) first_written = id;
      ++report.written;
    } else {
      ++report.refused;
      std::ostringstream line;
      line << standpoint.label_name << " from " << std::lround(standpoint.bearing_deg) << " deg, "
           << standpoint.distance_m << " m: " << result.refusal;
      report.refusals.push_back(line.str());
    }
    if (progress) progress(static_cast<int>(i + 1), static_cast<int>(standpoints.size()));
  }
  if (!first_written.valid()) {
    report.deleted = model.DeleteSyntheticViews();
  } else if (first_written.value() > 1) {  // id 1: the table was empty, nothing is old
    report.deleted = model.DeleteSyntheticViews(SyntheticViewId(first_written.value() - 1));
  }
  report.bytes = model.Summary().synthetic_view_bytes;
  report.seconds = SecondsSince(start);
  return report;
}

SIGHTMAP_OPTIONS_JSON(ViewSynthesisOptions, missing_sectors_only, coverage, max_pitch_deg,
                      grid_step_m, grid_clearance_m, grid_seen, max_sources, max_source_angle_deg,
                      mesh_step_px, max_edge_depth_ratio, max_depth_m, composite_depth_ratio,
                      min_drawn_share, min_features, features)

}  // namespace sightmap::synthesis
