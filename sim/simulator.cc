#include "sim/simulator.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "sim/random.h"

namespace sightmap::sim {
namespace {

uint64_t SessionSeed(uint64_t seed, int session) {
  return MixSeed(seed, 0x5e55'0000ULL + static_cast<uint64_t>(session));
}

// Lighting of a session: the ambient level and two roughly overhead lights differ per day.
render::RenderOptions SessionLighting(int session, uint64_t seed) {
  std::mt19937_64 rng(MixSeed(SessionSeed(seed, session), 11));
  render::RenderOptions options;
  options.near_m = 0.1;
  options.far_m = 250.0;  // the facade across the street is 25 m away, 150 m along a slant view
  // The only background a closed building shows is the sky through its windows: overcast.
  options.background_rgb = Eigen::Vector3f(0.82f, 0.85f, 0.9f);
  options.ambient = static_cast<float>(session == 1 ? 0.55 : UniformReal(rng, 0.42, 0.62));
  options.lights.clear();
  for (int i = 0; i < 2; ++i) {
    render::DirectionalLight light;
    const double azimuth = session == 1 ? 0.7 + 2.2 * i : UniformReal(rng, -kPi, kPi);
    const double elevation = session == 1 ? 0.9 : UniformReal(rng, 0.6, 1.2);
    light.direction_to_light =
        Eigen::Vector3f(static_cast<float>(std::cos(azimuth) * std::cos(elevation)),
                        static_cast<float>(std::sin(azimuth) * std::cos(elevation)),
                        static_cast<float>(std::sin(elevation)));
    light.intensity = static_cast<float>(session == 1 ? 0.3 : UniformReal(rng, 0.2, 0.38));
    options.lights.push_back(light);
  }
  return options;
}

}  // namespace

Intrinsics KinectIntrinsics() {
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = 525.0;
  k.fy = 525.0;
  k.cx = 319.5;
  k.cy = 239.5;
  return k;
}

const char* ToString(VisibilityType type) {
  switch (type) {
    case VisibilityType::kNotVisible:
      return "not_visible";
    case VisibilityType::kOccluded:
      return "occluded";
    case VisibilityType::kPartiallyVisible:
      return "partially_visible";
    case VisibilityType::kVisible:
      return "visible";
  }
  return "unknown";
}

bool SimulatorOptions::Check(std::string* error) const {
  if (scene.empty()) {
    *error = "scene must name 'office' or a scene file";
    return false;
  }
  if (session < 1) {
    *error = "session must be >= 1";
    return false;
  }
  if (!(fps > 0.0 && fps <= 120.0)) {
    *error = "fps must be in (0, 120]";
    return false;
  }
  if (frames < -1 || default_duration_s <= 0.0) {
    *error = "frames must be >= 0 (or -1 for the default) and default_duration_s > 0";
    return false;
  }
  return camera.Check(error) && depth.Check(error) && color.Check(error);
}

bool VisibilityThresholds::Check(std::string* error) const {
  if (id_buffer_downscale < 1 || min_pixels < 1 || occluded_below < 0.0 ||
      !(visible_from > occluded_below && visible_from <= 1.0)) {
    *error =
        "need id_buffer_downscale >= 1, min_pixels >= 1, 0 <= occluded_below < "
        "visible_from <= 1";
    return false;
  }
  return true;
}

bool QueryOptions::Check(std::string* error) const {
  if (width < 16 || height < 16 || !(hfov_deg > 10.0 && hfov_deg < 150.0)) {
    *error = "photo size must be at least 16x16 and hfov_deg in (10, 150)";
    return false;
  }
  if (!(min_distance_m > 0.0 && max_distance_m >= min_distance_m && min_height_m > 0.0 &&
        max_height_m >= min_height_m)) {
    *error = "need 0 < min_distance_m <= max_distance_m and 0 < min_height_m <= max_height_m";
    return false;
  }
  if (occluder_share < 0.0 || occluder_share > 1.0 || max_roll_deg < 0.0 ||
      max_yaw_jitter_deg < 0.0 || max_pitch_jitter_deg < 0.0 || max_hidden_target_redraws < 0 ||
      max_hidden_target_redraws > 255) {
    // A photo's redraws take the streams (index << 8) + 1..255: more would share the next one's.
    *error =
        "occluder_share must be in [0, 1], jitters >= 0 and max_hidden_target_redraws in [0, 255]";
    return false;
  }
  if (!(overhead_max_elevation_deg > 0.0 && overhead_max_elevation_deg <= 90.0) ||
      !(overhead_frame_offset_deg >= 0.0 && overhead_frame_offset_deg < 45.0) ||
      !(overhead_min_height_m > 0.0)) {
    *error =
        "overhead_max_elevation_deg must be in (0, 90], overhead_frame_offset_deg in [0, 45) "
        "and overhead_min_height_m positive";
    return false;
  }
  return thresholds.Check(error);
}

Intrinsics QueryOptions::PhoneIntrinsics() const {
  return Intrinsics::FromFieldOfView(width, height, DegToRad(hfov_deg), 0.0);
}

Simulator::Simulator(const SimulatorOptions& options) : options_(options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  scene_ = ApplySession(LoadScene(options.scene), options.session, options.seed);
  TrajectoryOptions trajectory_options;
  trajectory_options.kind = options.trajectory;
  trajectory_options.session = options.session;
  trajectory_options.seed = options.seed;
  trajectory_ = std::make_unique<Trajectory>(scene_, trajectory_options);
  renderer_ =
      std::make_unique<render::MeshRenderer>(SessionLighting(options.session, options.seed));
  AddSceneToRenderer(scene_, renderer_.get());
  // A survey is one lap by default: the capture ends where it began.
  const double default_duration_s = options.trajectory == TrajectoryKind::kSurvey
                                        ? trajectory_->lap_duration_s()
                                        : options.default_duration_s;
  num_frames_ = options.frames >= 0
                    ? options.frames
                    : static_cast<int64_t>(std::llround(default_duration_s * options.fps));
  std::mt19937_64 rng(MixSeed(SessionSeed(options.seed, options.session), 12));
  exposure_phase_ = UniformReal(rng, 0.0, 2 * kPi);
}

Simulator::~Simulator() = default;

TimestampNs Simulator::TimestampOf(int64_t index) const {
  return static_cast<TimestampNs>(std::llround(static_cast<double>(index) * 1e9 / options_.fps));
}

Eigen::Isometry3d Simulator::WorldFromCam(int64_t index) const {
  return trajectory_->WorldFromCam(static_cast<double>(TimestampOf(index)) * 1e-9);
}

RgbdFrame Simulator::RenderFrame(int64_t index) {
  SIGHTMAP_CHECK(index >= 0, "frame index must be >= 0");
  const double t = static_cast<double>(TimestampOf(index)) * 1e-9;
  const Eigen::Isometry3d world_from_cam = trajectory_->WorldFromCam(t);
  const Intrinsics& k = options_.camera;
  const render::RenderedView view = renderer_->Render(k, world_from_cam);

  // Image motion during the exposure: where a point 2 m ahead of the image centre moves.
  const Eigen::Isometry3d later = trajectory_->WorldFromCam(t + options_.color.exposure_s);
  const Eigen::Vector3d point = world_from_cam * Eigen::Vector3d(0, 0, 2.0);
  const Eigen::Vector3d point_later = later.inverse() * point;
  const Eigen::Vector2d blur =
      point_later.z() > 0.1 ? Eigen::Vector2d(k.Project(point_later) - Eigen::Vector2d(k.cx, k.cy))
                            : Eigen::Vector2d::Zero();
  // Auto-exposure hunting slowly around the session's level.
  const double gain = 1.0 + 0.08 * std::sin(2 * kPi * t / 17.0 + exposure_phase_);

  const uint64_t frame_seed =
      MixSeed(SessionSeed(options_.seed, options_.session), 1000 + static_cast<uint64_t>(index));
  RgbdFrame frame;
  frame.index = index;
  frame.timestamp_ns = TimestampOf(index);
  frame.color = SimulateColor(view.color, gain, blur, options_.color, MixSeed(frame_seed, 1));
  frame.depth = SimulateDepth(view.depth, view.no_depth, k, options_.depth, MixSeed(frame_seed, 2));
  frame.world_from_cam_gt = world_from_cam;
  return frame;
}

std::vector<ApplianceVisibility> Simulator::ClassifyAppliances(
    const Intrinsics& intrinsics, const Eigen::Isometry3d& world_from_cam,
    const VisibilityThresholds& thresholds) {
  SIGHTMAP_CHECK_OPTIONS(thresholds);
  const int n = thresholds.id_buffer_downscale;
  const Intrinsics small =
      intrinsics.Scaled(std::max(1, intrinsics.width / n), std::max(1, intrinsics.height / n));
  Intrinsics canvas = small;
  canvas.width = 3 * small.width;
  canvas.height = 3 * small.height;
  canvas.cx = small.cx + small.width;
  canvas.cy = small.cy + small.height;
  const cv::Mat ids = renderer_->RenderIds(small, world_from_cam);
  const Eigen::Isometry3d cam_from_world = world_from_cam.inverse();
  std::vector<ApplianceVisibility> result;
  for (const Appliance& appliance : scene_.appliances) {
    ApplianceVisibility v;
    v.appliance_id = appliance.id;
    v.visible_px = cv::countNonZero(ids == appliance.id);
    // Skip the footprint render when every part is behind the camera.
    bool in_front = false;
    for (const SceneBox& box : appliance.boxes) {
      in_front |= (cam_from_world * box.center).z() > -0.5 * box.size.norm();
    }
    if (in_front) {
      const cv::Mat alone = renderer_->RenderIds(canvas, world_from_cam, appliance.id);
      const cv::Mat mask = alone == appliance.id;
      v.footprint_px = cv::countNonZero(mask);
      v.in_image_px =
          cv::countNonZero(mask(cv::Rect(small.width, small.height, small.width, small.height)));
    }
    if (v.in_image_px < thresholds.min_pixels) {
      v.type = VisibilityType::kNotVisible;
    } else if (v.visible_px < thresholds.occluded_below * v.in_image_px) {
      v.type = VisibilityType::kOccluded;
    } else if (v.visible_px >= thresholds.visible_from * v.footprint_px) {
      v.type = VisibilityType::kVisible;
    } else {
      v.type = VisibilityType::kPartiallyVisible;
    }
    result.push_back(v);
  }
  return result;
}

QueryPhoto Simulator::RenderQuery(const Intrinsics& intrinsics,
                                  const Eigen::Isometry3d& world_from_cam,
                                  const VisibilityThresholds& thresholds, uint64_t noise_seed) {
  QueryPhoto photo = RenderQueryImage(intrinsics, world_from_cam, noise_seed);
  photo.visibility = ClassifyAppliances(intrinsics, world_from_cam, thresholds);
  return photo;
}

QueryPhoto Simulator::RenderQueryImage(const Intrinsics& intrinsics,
                                       const Eigen::Isometry3d& world_from_cam,
                                       uint64_t noise_seed) {
  QueryPhoto photo;
  photo.intrinsics = intrinsics;
  photo.world_from_cam = world_from_cam;
  const render::RenderedView view = renderer_->Render(intrinsics, world_from_cam);
  // A phone: less read noise than a Kinect's colour camera, no motion (photos are taken still).
  ColorSensorOptions phone = options_.color;
  phone.read_noise = 1.0;
  phone.shot_noise = 0.15;
  photo.image = SimulateColor(view.color, 1.0, Eigen::Vector2d::Zero(), phone, noise_seed);
  return photo;
}

namespace {

// Where a photo of `target` is taken from and how the phone is held: a free spot in the target's
// room at the wanted distance and height (rejection sampling), with furniture on the line of
// sight for options.occluder_share of the draws, aimed with a person's jitter. All draws from
// `rng`, in a fixed order.
struct QueryAim {
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  bool occluded = false;  // furniture on the line of sight to the target
};

QueryAim DrawQueryAim(const Scene& scene, const Appliance& target, const QueryOptions& options,
                      std::mt19937_64& rng) {
  const Eigen::Vector3d aim = target.points.front();
  const bool overhead = aim.z() > options.overhead_min_height_m;
  const Room* room = scene.RoomAt(aim.head<2>());
  const bool want_occluder = UniformReal(rng, 0.0, 1.0) < options.occluder_share;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool found = false;
  bool occluded = false;
  for (int attempt = 0; attempt < 1500 && !found; ++attempt) {
    const double angle = UniformReal(rng, -kPi, kPi);
    const double distance = UniformReal(rng, options.min_distance_m, options.max_distance_m);
    const double height = UniformReal(rng, options.min_height_m, options.max_height_m);
    const Eigen::Vector3d p(aim.x() + distance * std::cos(angle),
                            aim.y() + distance * std::sin(angle), height);
    if (room != nullptr && !room->Contains(p.head<2>(), 0.3)) continue;
    if (overhead && std::atan2(aim.z() - p.z(), (aim - p).head<2>().norm()) >
                        DegToRad(options.overhead_max_elevation_deg)) {
      continue;
    }
    if (!scene.IsFree(p, 0.25)) continue;
    const Eigen::Vector3d ray = aim - p;
    const auto hit = scene.Raycast(p, ray.normalized(), ray.norm() - 0.05, target.id);
    const bool blocked = hit.has_value();
    const bool by_wall = blocked && hit->second.rfind("wall", 0) == 0;
    if (by_wall) continue;  // a photo through a wall is not a photo of the appliance
    if (want_occluder && attempt < 1200 && !blocked) continue;
    if (!want_occluder && blocked) continue;
    position = p;
    occluded = blocked;
    found = true;
  }
  SIGHTMAP_CHECK(found, "found no place to photograph appliance "
                            << target.name << " from; check the scene's rooms and boxes");
  const Eigen::Vector3d to = aim - position;
  const double yaw = std::atan2(to.y(), to.x()) +
                     DegToRad(UniformReal(rng, -1.0, 1.0) * options.max_yaw_jitter_deg);
  const double frame_offset = overhead ? DegToRad(options.overhead_frame_offset_deg) : 0.0;
  const double pitch = std::atan2(to.z(), to.head<2>().norm()) - frame_offset +
                       DegToRad(UniformReal(rng, -1.0, 1.0) * options.max_pitch_jitter_deg);
  const double roll = DegToRad(UniformReal(rng, -1.0, 1.0) * options.max_roll_deg);
  QueryAim result;
  result.world_from_cam.linear() = WorldFromCamRotation(yaw, pitch, roll);
  result.world_from_cam.translation() = position;
  result.occluded = occluded;
  return result;
}

}  // namespace

bool ShowsAppliance(const std::vector<ApplianceVisibility>& visibility, int appliance_id) {
  for (const ApplianceVisibility& v : visibility) {
    if (v.appliance_id != appliance_id) continue;
    return v.type == VisibilityType::kVisible || v.type == VisibilityType::kPartiallyVisible;
  }
  return false;
}

std::vector<QueryPhoto> Simulator::MakeQueries(int count, const QueryOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(!scene_.appliances.empty(), "the scene has no appliances to photograph");
  const Intrinsics phone = options.PhoneIntrinsics();
  const uint64_t seed = MixSeed(SessionSeed(options_.seed, options_.session), 77);
  std::mt19937_64 rng(seed);
  // Appliances in a shuffled order (Fisher-Yates with our own uniform draws), cycled.
  std::vector<size_t> order(scene_.appliances.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (size_t i = order.size(); i > 1; --i) {
    const size_t j = static_cast<size_t>(UniformReal(rng, 0.0, static_cast<double>(i)));
    std::swap(order[i - 1], order[std::min(j, i - 1)]);
  }
  std::vector<QueryPhoto> photos;
  for (int q = 0; q < count; ++q) {
    const Appliance& target = scene_.appliances[order[static_cast<size_t>(q) % order.size()]];
    QueryAim aim = DrawQueryAim(scene_, target, options, rng);
    uint64_t noise_seed = rng();
    std::vector<ApplianceVisibility> visibility =
        ClassifyAppliances(phone, aim.world_from_cam, options.thresholds);
    // A person photographs an appliance they can see. Furniture on the line of sight to its
    // centre may still hide all of it; such a photo is drawn again, from a stream of its own so
    // that the other photos stay as they are. Only the draw kept is rendered.
    for (int redraw = 1;
         redraw <= options.max_hidden_target_redraws && !ShowsAppliance(visibility, target.id);
         ++redraw) {
      std::mt19937_64 again(
          MixSeed(seed, (static_cast<uint64_t>(q) << 8) + static_cast<uint64_t>(redraw)));
      aim = DrawQueryAim(scene_, target, options, again);
      noise_seed = again();
      visibility = ClassifyAppliances(phone, aim.world_from_cam, options.thresholds);
    }
    QueryPhoto photo = RenderQueryImage(phone, aim.world_from_cam, noise_seed);
    photo.visibility = std::move(visibility);
    photo.index = q;
    photo.target_appliance = target.id;
    photo.with_occluder = aim.occluded;
    photos.push_back(std::move(photo));
  }
  return photos;
}

cv::Mat DrawOverview(const Scene& scene, const std::vector<Eigen::Isometry3d>& trajectory,
                     const std::vector<QueryPhoto>& queries, double pixels_per_m) {
  Eigen::AlignedBox2d bounds;
  for (const Room& room : scene.rooms) bounds.extend(room.min).extend(room.max);
  const double margin = 1.0;
  const int width = static_cast<int>((bounds.sizes().x() + 2 * margin) * pixels_per_m);
  const int height = static_cast<int>((bounds.sizes().y() + 2 * margin) * pixels_per_m);
  cv::Mat image(height, width, CV_8UC3, cv::Scalar(250, 250, 250));
  // North up: image y grows southwards.
  auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point(
        static_cast<int>(std::lround((p.x() - bounds.min().x() + margin) * pixels_per_m)),
        static_cast<int>(std::lround((bounds.max().y() + margin - p.y()) * pixels_per_m)));
  };
  for (const Room& room : scene.rooms) {
    cv::rectangle(image, to_px(room.min), to_px(room.max), cv::Scalar(235, 238, 240), cv::FILLED);
    cv::putText(image, room.name, to_px(Eigen::Vector2d(room.min.x() + 0.2, room.max.y() - 0.5)),
                cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(120, 120, 120), 1, cv::LINE_AA);
  }
  auto draw_box = [&](const SceneBox& box, const cv::Scalar& colour) {
    if (box.center.z() - 0.5 * box.size.z() > 2.0) return;    // ceiling-mounted: not an obstacle
    if (box.size.z() < 0.15 && box.center.z() < 0.1) return;  // floors
    std::vector<cv::Point> corners;
    const Eigen::Matrix2d r = Eigen::Rotation2Dd(box.yaw_rad).toRotationMatrix();
    for (const auto& s : {Eigen::Vector2d(-1, -1), Eigen::Vector2d(1, -1), Eigen::Vector2d(1, 1),
                          Eigen::Vector2d(-1, 1)}) {
      corners.push_back(to_px(box.center.head<2>() +
                              r * Eigen::Vector2d(s.x() * box.size.x(), s.y() * box.size.y()) / 2));
    }
    cv::fillConvexPoly(image, corners, colour, cv::LINE_AA);
  };
  for (const SceneBox& box : scene.boxes) {
    const bool wall = box.name.rfind("wall", 0) == 0;
    draw_box(box, wall ? cv::Scalar(60, 60, 60) : cv::Scalar(170, 185, 200));
  }
  for (size_t i = 1; i < trajectory.size(); ++i) {
    cv::line(image, to_px(trajectory[i - 1].translation().head<2>()),
             to_px(trajectory[i].translation().head<2>()), cv::Scalar(200, 120, 30), 2,
             cv::LINE_AA);
  }
  if (!trajectory.empty()) {
    cv::circle(image, to_px(trajectory.front().translation().head<2>()), 6, cv::Scalar(0, 160, 0),
               cv::FILLED, cv::LINE_AA);
  }
  for (const QueryPhoto& photo : queries) {
    const Eigen::Vector2d p = photo.world_from_cam.translation().head<2>();
    const Eigen::Vector3d forward = photo.world_from_cam.linear().col(2);
    cv::arrowedLine(image, to_px(p), to_px(p + 0.5 * forward.head<2>().normalized()),
                    cv::Scalar(160, 40, 160), 1, cv::LINE_AA, 0, 0.3);
  }
  for (const Appliance& appliance : scene.appliances) {
    for (const Eigen::Vector3d& p : appliance.points) {
      cv::circle(image, to_px(p.head<2>()), 5, cv::Scalar(0, 0, 220), cv::FILLED, cv::LINE_AA);
    }
    cv::putText(image, appliance.name, to_px(appliance.points.front().head<2>()) + cv::Point(6, -4),
                cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(0, 0, 160), 1, cv::LINE_AA);
  }
  return image;
}

}  // namespace sightmap::sim
