#include "render/map_renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "render/bitmap_font.h"
#include "render/gl_api.h"
#include "render/gl_camera.h"

namespace sightmap::render {

// One vertex of the point and line buffers: 16 bytes, position then RGBA. Outside the anonymous
// namespace because MapRenderer::Impl holds a buffer of them.
struct ColorVertex {
  float x, y, z;
  uint8_t r, g, b, a;
};
static_assert(sizeof(ColorVertex) == 16, "ColorVertex must be tightly packed");

namespace {

ColorVertex MakeVertex(const Eigen::Vector3d& p, const Eigen::Vector3f& rgb) {
  auto byte = [](float c) {
    return static_cast<uint8_t>(std::clamp(c, 0.0f, 1.0f) * 255.0f + 0.5f);
  };
  return {static_cast<float>(p.x()),
          static_cast<float>(p.y()),
          static_cast<float>(p.z()),
          byte(rgb.x()),
          byte(rgb.y()),
          byte(rgb.z()),
          255};
}

// world_from_cam of a camera at `eye` looking at `target` with image-up along `up`.
Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(up);
  if (x.norm() < 1e-6) x = z.unitOrthogonal();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = y;
  pose.linear().col(2) = z;
  pose.translation() = eye;
  return pose;
}

Eigen::Vector3f TrackingColor(TrackingState state) {
  switch (state) {
    case TrackingState::kTracking:
      return {0.25f, 1.0f, 0.3f};
    case TrackingState::kLost:
      return {1.0f, 0.2f, 0.2f};
    case TrackingState::kRelocalised:
      return {1.0f, 0.85f, 0.2f};
  }
  return {1, 1, 1};
}

// Whether a sphere (centre in the view's camera frame) may reach the view volume; conservative.
bool SphereMayBeVisible(const ViewCamera& view, const Eigen::Vector3d& c, double r) {
  if (c.z() + r < view.near_m || c.z() - r > view.far_m) return false;
  const Intrinsics& k = view.intrinsics;
  // The image rectangle in normalised (perspective) or metric (orthographic) coordinates.
  const double left = -(k.cx + 0.5) / k.fx;
  const double right = (k.width - 0.5 - k.cx) / k.fx;
  const double top = -(k.cy + 0.5) / k.fy;
  const double bottom = (k.height - 0.5 - k.cy) / k.fy;
  if (view.orthographic) {
    return c.x() + r >= left && c.x() - r <= right && c.y() + r >= top && c.y() - r <= bottom;
  }
  // Side planes through the optical centre: a point is inside when x >= left * z, etc.
  auto outside = [&](double a, double b, double sign) {
    // Plane sign * (x_or_y - slope * z) >= 0 with unit normal; distance of the centre.
    const double norm = std::sqrt(1.0 + b * b);
    return sign * (a - b * c.z()) / norm < -r;
  };
  return !(outside(c.x(), left, 1.0) || outside(c.x(), right, -1.0) || outside(c.y(), top, 1.0) ||
           outside(c.y(), bottom, -1.0));
}

std::string FormatCount(double n) {
  char text[32];
  if (n >= 1e6) {
    std::snprintf(text, sizeof(text), "%.2fM", n / 1e6);
  } else if (n >= 1e4) {
    std::snprintf(text, sizeof(text), "%.0fk", n / 1e3);
  } else {
    std::snprintf(text, sizeof(text), "%.0f", n);
  }
  return text;
}

}  // namespace

bool MapRenderOptions::Check(std::string* error) const {
  if (width < 16 || height < 16) {
    *error = "the progress image must be at least 16x16 pixels";
    return false;
  }
  if (!(point_size_px >= 1.0f && trajectory_width_px >= 1.0f) || text_scale < 1) {
    *error = "point size, line width and text scale must be at least 1";
    return false;
  }
  if (!(top_down_margin >= 0.0 && top_down_margin < 0.4)) {
    *error = "top_down_margin must be in [0, 0.4)";
    return false;
  }
  if (!(floor_brightness >= 0.0 && floor_brightness <= 1.0)) {
    *error = "floor_brightness must be in [0, 1]";
    return false;
  }
  if (!(follow_distance_m >= 0.0 && follow_hfov_deg > 1.0 && follow_hfov_deg < 170.0 &&
        frustum_depth_m > 0.0)) {
    *error = "follow view needs distance >= 0, a field of view in (1, 170) degrees, frustum > 0";
    return false;
  }
  return coverage.Check(error);
}

std::string CoverageLine(const MapScene& scene, const SectorOptions& options) {
  if (scene.appliances().empty()) return "";
  int seen = 0;
  for (const uint64_t sectors : scene.SeenSectors(options)) seen += __builtin_popcountll(sectors);
  const size_t directions = scene.appliances().size() * static_cast<size_t>(options.sectors);
  return "labels " + std::to_string(scene.appliances().size()) + "  seen from " +
         std::to_string(seen) + " of " + std::to_string(directions) + " directions";
}

std::optional<Eigen::Vector2d> ViewCamera::ProjectOnPlan(const Eigen::Vector3d& world_point) const {
  if (!orthographic) return Project(world_point);
  const Eigen::Vector3d p = world_from_cam.inverse() * world_point;
  return Eigen::Vector2d(intrinsics.cx + intrinsics.fx * p.x(),
                         intrinsics.cy + intrinsics.fy * p.y());
}

std::optional<Eigen::Vector2d> ViewCamera::Project(const Eigen::Vector3d& world_point) const {
  const Eigen::Vector3d p = world_from_cam.inverse() * world_point;
  if (p.z() < near_m || p.z() > far_m) return std::nullopt;
  if (orthographic) {
    return Eigen::Vector2d(intrinsics.cx + intrinsics.fx * p.x(),
                           intrinsics.cy + intrinsics.fy * p.y());
  }
  return intrinsics.Project(p);
}

ViewCamera TopDownCamera(const MapScene& scene, int width, int height,
                         const MapRenderOptions& options) {
  const Eigen::Vector3d& up = scene.world_up();
  Eigen::Vector3d e1, e2;
  FloorAxes(up, &e1, &e2);
  const std::vector<Eigen::Vector3d> sample = scene.ExtentSample();
  Eigen::Vector2d lo(-5, -5), hi(5, 5);
  double min_height = 0.0;
  double top = 2.0;
  if (!sample.empty()) {
    lo = Eigen::Vector2d::Constant(1e300);
    hi = -lo;
    min_height = 1e300;
    double max_height = -1e300;
    for (const Eigen::Vector3d& p : sample) {
      const Eigen::Vector2d q(p.dot(e1), p.dot(e2));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
      min_height = std::min(min_height, p.dot(up));
      max_height = std::max(max_height, p.dot(up));
    }
    // The cut: above the highest camera, or above everything when there is no camera.
    double camera_top = -1e300;
    for (const auto& [id, keyframe] : scene.keyframes()) {
      camera_top = std::max(camera_top, keyframe.world_from_cam.translation().dot(up));
    }
    if (scene.camera()) camera_top = std::max(camera_top, scene.camera()->translation().dot(up));
    top =
        camera_top > -1e300 ? camera_top + options.top_down_cut_above_camera_m : max_height + 0.01;
  }
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  const Eigen::Vector2d extent = (hi - lo).cwiseMax(Eigen::Vector2d(1.0, 1.0));
  const double usable = 1.0 - 2.0 * options.top_down_margin;
  const double metres_per_px =
      std::max(extent.x() / (usable * width), extent.y() / (usable * height));

  ViewCamera view;
  view.orthographic = true;
  view.intrinsics.width = width;
  view.intrinsics.height = height;
  view.intrinsics.fx = view.intrinsics.fy = 1.0 / metres_per_px;
  view.intrinsics.cx = 0.5 * (width - 1);
  view.intrinsics.cy = 0.5 * (height - 1);
  view.world_from_cam.linear().col(0) = e1;
  view.world_from_cam.linear().col(1) = -e2;
  view.world_from_cam.linear().col(2) = -up;
  view.world_from_cam.translation() = centre.x() * e1 + centre.y() * e2 + top * up;
  view.near_m = 0.0;
  const double depth_range = std::max(0.0, top - std::min(min_height, top));
  view.far_m = depth_range + 1.0;
  if (options.floor_brightness < 1.0 && depth_range > 0.2) {
    view.depth_cue_m = depth_range / (1.0 - options.floor_brightness);
  }
  return view;
}

ViewCamera FollowCamera(const MapScene& scene, int width, int height,
                        const MapRenderOptions& options) {
  const Eigen::Vector3d& up = scene.world_up();
  Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  if (scene.camera()) {
    camera = *scene.camera();
  } else if (!scene.keyframes().empty()) {
    camera = scene.keyframes().rbegin()->second.world_from_cam;
  }
  // Heading on the floor: the optical axis, or image-up when looking straight up or down.
  Eigen::Vector3d forward = camera.linear().col(2);
  forward -= forward.dot(up) * up;
  if (forward.norm() < 1e-3) {
    forward = -camera.linear().col(1);
    forward -= forward.dot(up) * up;
  }
  if (forward.norm() < 1e-3) {
    Eigen::Vector3d e2;
    FloorAxes(up, &forward, &e2);
  }
  forward.normalize();
  const Eigen::Vector3d c = camera.translation();
  const Eigen::Vector3d eye =
      c - options.follow_distance_m * forward + options.follow_height_m * up;
  const Eigen::Vector3d target = c + options.look_ahead_m * forward;

  ViewCamera view;
  view.intrinsics =
      Intrinsics::FromFieldOfView(width, height, DegToRad(options.follow_hfov_deg), 0.0);
  view.world_from_cam = LookAt(eye, target, up);
  view.near_m = 0.1;
  view.far_m = 200.0;
  return view;
}

ViewCamera OrbitCamera(const Eigen::Vector3d& target, double yaw_rad, double pitch_rad,
                       double distance_m, const Eigen::Vector3d& world_up, int width, int height,
                       double hfov_deg) {
  const Eigen::Vector3d up = world_up.normalized();
  Eigen::Vector3d e1, e2;
  FloorAxes(up, &e1, &e2);
  const double pitch = std::clamp(pitch_rad, DegToRad(-89.0), DegToRad(89.0));
  const Eigen::Vector3d direction =
      std::cos(pitch) * (std::cos(yaw_rad) * e1 + std::sin(yaw_rad) * e2) + std::sin(pitch) * up;
  ViewCamera view;
  view.intrinsics = Intrinsics::FromFieldOfView(width, height, DegToRad(hfov_deg), 0.0);
  view.world_from_cam = LookAt(target + std::max(distance_m, 0.01) * direction, target, up);
  view.near_m = std::max(0.01, 0.01 * distance_m);
  view.far_m = 200.0 + distance_m;
  return view;
}

ProgressLayout MakeProgressLayout(const MapScene& scene, int width, int height,
                                  const MapRenderOptions& options) {
  ProgressLayout layout;
  const int left = width / 2;
  layout.top_down_viewport = {0, 0, left, height};
  layout.follow_viewport = {left, 0, width - left, height};
  layout.top_down = TopDownCamera(scene, left, height, options);
  layout.follow = FollowCamera(scene, width - left, height, options);
  return layout;
}

struct MapRenderer::Impl {
  struct KeyframeBuffer {
    GLuint buffer = 0;
    GLsizei count = 0;
    uint64_t version = 0;
    Eigen::Vector3d centre_cam = Eigen::Vector3d::Zero();  // bounding sphere, keyframe frame
    double radius = 0.0;
  };

  GlApi gl;
  MapRenderOptions options;
  std::map<int64_t, KeyframeBuffer> buffers;
  size_t uploads = 0;
  size_t uploaded_points = 0;
  size_t points_drawn = 0;
  GLuint image_texture = 0;
  int framebuffer_width = 0;
  int framebuffer_height = 0;
  std::vector<ColorVertex> scratch;  // reused upload staging

  // Restricts drawing to `viewport` (y down in our convention, up in GL's).
  void SetViewport(const Viewport& v) {
    const int gl_y = framebuffer_height - v.y - v.height;
    gl.Viewport(v.x, gl_y, v.width, v.height);
    gl.Scissor(v.x, gl_y, v.width, v.height);
    gl.Enable(GL_SCISSOR_TEST);
  }

  // Pixel coordinates of `v` (x right, y down, origin at its top-left) for 2D drawing.
  void Begin2D(const Viewport& v) {
    SetViewport(v);
    Eigen::Matrix4d p = Eigen::Matrix4d::Identity();
    p(0, 0) = 2.0 / v.width;
    p(0, 3) = -1.0;
    p(1, 1) = -2.0 / v.height;
    p(1, 3) = 1.0;
    gl.MatrixMode(GL_PROJECTION);
    gl.LoadMatrixd(p.data());
    gl.MatrixMode(GL_MODELVIEW);
    gl.LoadIdentity();
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_FOG);
  }

  Viewport Whole() const { return {0, 0, framebuffer_width, framebuffer_height}; }

  // The coverage ring's radii, in font pixels.
  static constexpr float kRingInner = 5.0f;
  static constexpr float kRingOuter = 9.0f;

  // Sectors around an appliance at screen (x, y): seen ones green, the others red, each a band
  // between two radii [px] drawn as a few quads (the floor plan's screen may mirror the floor, so
  // each edge's screen direction is projected).
  // `pixel` is where the view projects `centre` (ViewCamera::ProjectOnPlan).
  void CoverageRing(const MapScene& scene, const ViewCamera& view, const Eigen::Vector3d& centre,
                    const Eigen::Vector2d& pixel, uint64_t seen) {
    const int sectors = options.coverage.sectors;
    constexpr int kStepsPerSector = 4;
    const float inner = kRingInner * static_cast<float>(options.text_scale);
    const float outer = kRingOuter * static_cast<float>(options.text_scale);
    auto edge = [&](int step) {  // the screen direction of a bearing step
      const double bearing = 360.0 * step / (sectors * kStepsPerSector);
      const std::optional<Eigen::Vector2d> tip =
          view.ProjectOnPlan(centre + scene.FloorDirection(bearing));
      Eigen::Vector2d d = tip ? Eigen::Vector2d(*tip - pixel) : Eigen::Vector2d::UnitX();
      if (d.norm() < 1e-9) d = Eigen::Vector2d::UnitX();
      return Eigen::Vector2f(d.normalized().cast<float>());
    };
    std::vector<Eigen::Vector2f> green;
    std::vector<Eigen::Vector2f> red;
    const Eigen::Vector2f c = (pixel.array() + 0.5).matrix().cast<float>();
    for (int s = 0; s < sectors; ++s) {
      std::vector<Eigen::Vector2f>& out = (seen >> s) & 1 ? green : red;
      for (int k = 0; k < kStepsPerSector; ++k) {
        const int step = s * kStepsPerSector + k;
        // A hair short of the next sector, so that neighbours stay apart.
        const Eigen::Vector2f a = edge(step);
        const Eigen::Vector2f b =
            k + 1 < kStepsPerSector ? edge(step + 1) : (0.85f * edge(step + 1) + 0.15f * a);
        const Eigen::Vector2f p0 = c + inner * a, p1 = c + outer * a;
        const Eigen::Vector2f p2 = c + outer * b, p3 = c + inner * b;
        out.insert(out.end(), {p0, p1, p2, p0, p2, p3});
      }
    }
    Triangles2D(green, Eigen::Vector4f(0.2f, 0.85f, 0.3f, 1.0f));
    Triangles2D(red, Eigen::Vector4f(0.75f, 0.15f, 0.15f, 1.0f));
  }

  void Triangles2D(const std::vector<Eigen::Vector2f>& vertices, const Eigen::Vector4f& rgba) {
    if (vertices.empty()) return;
    const bool blend = rgba.w() < 1.0f;
    if (blend) {
      gl.Enable(GL_BLEND);
      gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    }
    gl.Color4f(rgba.x(), rgba.y(), rgba.z(), rgba.w());
    gl.EnableClientState(GL_VERTEX_ARRAY);
    gl.VertexPointer(2, GL_FLOAT, sizeof(Eigen::Vector2f), vertices.data());
    gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(vertices.size()));
    gl.DisableClientState(GL_VERTEX_ARRAY);
    if (blend) gl.Disable(GL_BLEND);
  }

  static void AppendRect(float x0, float y0, float x1, float y1,
                         std::vector<Eigen::Vector2f>* out) {
    out->insert(out->end(), {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y0}, {x1, y1}, {x0, y1}});
  }

  // Text at (x, y) of the current 2D viewport, on a translucent dark backing.
  void Text2D(std::string_view text, float x, float y, int scale, const Eigen::Vector3f& rgb,
              bool backing = true) {
    if (backing) {
      std::vector<Eigen::Vector2f> rect;
      const float pad = 2.0f * scale;
      AppendRect(x - pad, y - pad, x + TextWidthPx(text, scale) + pad,
                 y + TextHeightPx(text, scale) + pad, &rect);
      Triangles2D(rect, Eigen::Vector4f(0, 0, 0, 0.6f));
    }
    std::vector<Eigen::Vector2f> glyphs;
    AppendTextTriangles(text, x, y, static_cast<float>(scale), &glyphs);
    Triangles2D(glyphs, Eigen::Vector4f(rgb.x(), rgb.y(), rgb.z(), 1.0f));
  }

  void Lines(const std::vector<ColorVertex>& vertices, GLenum mode, float width) {
    if (vertices.empty()) return;
    gl.LineWidth(width);
    gl.PointSize(width);
    gl.EnableClientState(GL_VERTEX_ARRAY);
    gl.EnableClientState(GL_COLOR_ARRAY);
    gl.VertexPointer(3, GL_FLOAT, sizeof(ColorVertex), &vertices[0].x);
    gl.ColorPointer(4, GL_UNSIGNED_BYTE, sizeof(ColorVertex), &vertices[0].r);
    gl.DrawArrays(mode, 0, static_cast<GLsizei>(vertices.size()));
    gl.DisableClientState(GL_COLOR_ARRAY);
    gl.DisableClientState(GL_VERTEX_ARRAY);
  }

  // DrawMap's stages, in order.
  // Loads the view's projection; returns the world's eye frame (the model-view of world points).
  Eigen::Matrix4d SetCamera(const ViewCamera& view) {
    gl.Clear(GL_DEPTH_BUFFER_BIT);
    gl.MatrixMode(GL_PROJECTION);
    const Eigen::Matrix4d projection =
        view.orthographic ? GlOrthographic(view.intrinsics, view.near_m, view.far_m)
                          : GlPerspective(view.intrinsics, view.near_m, view.far_m);
    gl.LoadMatrixd(projection.data());  // Eigen is column-major like GL
    gl.MatrixMode(GL_MODELVIEW);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    return GlEyeFromCam() * view.world_from_cam.inverse().matrix();
  }

  // The keyframes' points, one buffer per keyframe with its pose as model matrix: those whose
  // bounding sphere meets the view volume, thinned to max_points_per_pixel, fogged by depth_cue_m.
  void DrawPoints(const MapScene& scene, const ViewCamera& view, const Viewport& viewport,
                  const Eigen::Matrix4d& eye_from_world) {
    if (view.depth_cue_m > 0.0) {
      const Eigen::Vector3f& bg = options.background_rgb;
      const GLfloat fog_color[4] = {bg.x(), bg.y(), bg.z(), 1.0f};
      gl.Enable(GL_FOG);
      gl.Fogi(GL_FOG_MODE, GL_LINEAR);
      gl.Fogf(GL_FOG_START, 0.0f);
      gl.Fogf(GL_FOG_END, static_cast<float>(view.depth_cue_m));
      gl.Fogfv(GL_FOG_COLOR, fog_color);
    }
    const Eigen::Isometry3d cam_from_world = view.world_from_cam.inverse();
    std::vector<std::pair<const KeyframeBuffer*, const MapKeyframe*>> visible;
    size_t visible_points = 0;
    for (const auto& [id, buffer] : buffers) {
      const auto it = scene.keyframes().find(id);
      if (it == scene.keyframes().end() || buffer.count == 0) continue;
      const Eigen::Vector3d c = cam_from_world * (it->second.world_from_cam * buffer.centre_cam);
      if (!SphereMayBeVisible(view, c, buffer.radius)) continue;
      visible.emplace_back(&buffer, &it->second);
      visible_points += static_cast<size_t>(buffer.count);
    }
    double fraction = 1.0;
    if (options.max_points_per_pixel > 0.0 && visible_points > 0) {
      const double budget = options.max_points_per_pixel * viewport.width * viewport.height;
      fraction = std::min(1.0, budget / static_cast<double>(visible_points));
    }
    points_drawn = 0;
    gl.PointSize(options.point_size_px);
    gl.EnableClientState(GL_VERTEX_ARRAY);
    gl.EnableClientState(GL_COLOR_ARRAY);
    for (const auto& [buffer, keyframe] : visible) {
      const GLsizei count =
          std::min(buffer->count, static_cast<GLsizei>(std::ceil(buffer->count * fraction)));
      const Eigen::Matrix4d model_view = eye_from_world * keyframe->world_from_cam.matrix();
      gl.LoadMatrixd(model_view.data());
      gl.BindBuffer(GL_ARRAY_BUFFER, buffer->buffer);
      gl.VertexPointer(3, GL_FLOAT, sizeof(ColorVertex), nullptr);
      gl.ColorPointer(4, GL_UNSIGNED_BYTE, sizeof(ColorVertex),
                      reinterpret_cast<const void*>(offsetof(ColorVertex, r)));
      gl.DrawArrays(GL_POINTS, 0, count);
      points_drawn += static_cast<size_t>(count);
    }
    gl.BindBuffer(GL_ARRAY_BUFFER, 0);
    gl.DisableClientState(GL_COLOR_ARRAY);
    gl.DisableClientState(GL_VERTEX_ARRAY);
    gl.Disable(GL_FOG);
  }

  // Trajectories (one polyline per session), keyframe dots and loop edges, in world coordinates;
  // on the floor plan on top of everything.
  void DrawWalk(const MapScene& scene, const ViewCamera& view,
                const Eigen::Matrix4d& eye_from_world) {
    gl.LoadMatrixd(eye_from_world.data());
    if (view.orthographic) gl.Disable(GL_DEPTH_TEST);
    std::vector<ColorVertex> lines;
    std::vector<ColorVertex> dots;
    std::map<int, const MapKeyframe*> last_of_session;
    for (const auto& [id, keyframe] : scene.keyframes()) {
      const Eigen::Vector3f color = SessionColor(keyframe.session);
      const Eigen::Vector3d position = keyframe.world_from_cam.translation();
      auto it = last_of_session.find(keyframe.session);
      if (it != last_of_session.end()) {
        lines.push_back(MakeVertex(it->second->world_from_cam.translation(), color));
        lines.push_back(MakeVertex(position, color));
      }
      last_of_session[keyframe.session] = &keyframe;
      dots.push_back(MakeVertex(position, color));
    }
    const Eigen::Vector3f loop_color(1.0f, 0.25f, 0.9f);
    for (const LoopEdge& edge : scene.loops()) {
      const auto a = scene.keyframes().find(edge.from_id);
      const auto b = scene.keyframes().find(edge.to_id);
      if (a == scene.keyframes().end() || b == scene.keyframes().end()) continue;
      lines.push_back(MakeVertex(a->second.world_from_cam.translation(), loop_color));
      lines.push_back(MakeVertex(b->second.world_from_cam.translation(), loop_color));
    }
    Lines(lines, GL_LINES, options.trajectory_width_px);
    Lines(dots, GL_POINTS, options.trajectory_width_px + 1.0f);
  }

  // The current camera's frustum, always on top, coloured by the tracking state; on the floor
  // plan at least 14 px deep.
  void DrawCamera(const MapScene& scene, const ViewCamera& view) {
    gl.Disable(GL_DEPTH_TEST);
    if (!scene.camera()) return;
    double depth = options.frustum_depth_m;
    if (view.orthographic) depth = std::max(depth, 14.0 / view.intrinsics.fx);
    const Eigen::Vector3f color = TrackingColor(scene.status().tracking);
    const Eigen::Isometry3d& pose = *scene.camera();
    const Eigen::Vector3d apex = pose.translation();
    Eigen::Vector3d corners[4];
    const double hx = 0.55 * depth;  // about the Kinect's 58 x 45 degrees
    const double hy = 0.41 * depth;
    corners[0] = pose * Eigen::Vector3d(-hx, -hy, depth);
    corners[1] = pose * Eigen::Vector3d(hx, -hy, depth);
    corners[2] = pose * Eigen::Vector3d(hx, hy, depth);
    corners[3] = pose * Eigen::Vector3d(-hx, hy, depth);
    std::vector<ColorVertex> frustum;
    for (int i = 0; i < 4; ++i) {
      frustum.push_back(MakeVertex(apex, color));
      frustum.push_back(MakeVertex(corners[i], color));
      frustum.push_back(MakeVertex(corners[i], color));
      frustum.push_back(MakeVertex(corners[(i + 1) % 4], color));
    }
    Lines(frustum, GL_LINES, 2.0f);
  }

  // Appliances: a marker and the name, in screen space so they stay readable at any zoom; on the
  // floor plan, where they hang whatever their height (a ceiling light above the plan's cut),
  // with the ring of directions they were seen from. The names first, then the rings and markers
  // over them, so that no name's backing hides a neighbour's ring.
  void DrawAppliances(const MapScene& scene, const ViewCamera& view, const Viewport& viewport) {
    Begin2D(viewport);
    const int scale = options.text_scale;
    const float r = 3.0f * scale;
    const bool rings = view.orthographic && options.show_coverage;
    const float clear = rings ? kRingOuter * static_cast<float>(scale) : r;
    const std::vector<uint64_t> seen =
        rings ? scene.SeenSectors(options.coverage) : std::vector<uint64_t>();
    std::vector<std::pair<size_t, Eigen::Vector2d>> placed;  // appliance, pixel
    for (size_t a = 0; a < scene.appliances().size(); ++a) {
      const ApplianceLabel& label = scene.appliances()[a];
      const std::optional<Eigen::Vector2d> pixel = view.ProjectOnPlan(label.world_point);
      if (!pixel) continue;
      const float x = static_cast<float>(pixel->x()) + 0.5f;
      const float y = static_cast<float>(pixel->y()) + 0.5f;
      placed.emplace_back(a, *pixel);
      // Right of the marker (and its ring), or left of it when the name would leave the viewport.
      float text_x = x + clear + scale;
      if (text_x + TextWidthPx(label.name, scale) > viewport.width) {
        text_x = x - clear - scale - TextWidthPx(label.name, scale);
      }
      Text2D(label.name, text_x, y - 3.5f * scale, scale, Eigen::Vector3f(1.0f, 0.95f, 0.6f));
    }
    for (const auto& [a, pixel] : placed) {
      const float x = static_cast<float>(pixel.x()) + 0.5f;
      const float y = static_cast<float>(pixel.y()) + 0.5f;
      if (rings) CoverageRing(scene, view, scene.appliances()[a].world_point, pixel, seen[a]);
      std::vector<Eigen::Vector2f> marker = {{x, y - r}, {x + r, y}, {x, y + r},
                                             {x, y - r}, {x, y + r}, {x - r, y}};
      Triangles2D(marker, Eigen::Vector4f(1.0f, 0.9f, 0.1f, 1.0f));
    }
  }
};

MapRenderer::MapRenderer(GlProcLoader loader, const MapRenderOptions& options)
    : impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_->options = options;
  impl_->gl.Load(loader);
}

MapRenderer::~MapRenderer() {
  if (!impl_) return;
  const GlApi& gl = impl_->gl;
  for (auto& [id, buffer] : impl_->buffers) gl.DeleteBuffers(1, &buffer.buffer);
  if (impl_->image_texture != 0) gl.DeleteTextures(1, &impl_->image_texture);
}

const MapRenderOptions& MapRenderer::options() const { return impl_->options; }
size_t MapRenderer::num_uploads() const { return impl_->uploads; }
size_t MapRenderer::num_uploaded_points() const { return impl_->uploaded_points; }
size_t MapRenderer::num_points_drawn() const { return impl_->points_drawn; }

void MapRenderer::Sync(const MapScene& scene) {
  Impl& impl = *impl_;
  const GlApi& gl = impl.gl;
  // Free the buffers of keyframes that left the scene.
  for (auto it = impl.buffers.begin(); it != impl.buffers.end();) {
    if (scene.keyframes().count(it->first) == 0) {
      gl.DeleteBuffers(1, &it->second.buffer);
      it = impl.buffers.erase(it);
    } else {
      ++it;
    }
  }
  for (const auto& [id, keyframe] : scene.keyframes()) {
    Impl::KeyframeBuffer& buffer = impl.buffers[id];
    const uint64_t version = scene.points_version(id);
    if (buffer.version == version) continue;
    if (buffer.buffer == 0) gl.GenBuffers(1, &buffer.buffer);
    // Shuffled (reproducibly), so that any prefix is a uniform subset: the level of detail.
    std::vector<ColorVertex>& data = impl.scratch;
    const size_t n = keyframe.points_cam.size();
    data.resize(n);
    Eigen::AlignedBox3d box;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f& p = keyframe.points_cam[i];
      const auto& c = keyframe.colors[i];
      data[i] = {p.x(), p.y(), p.z(), c[0], c[1], c[2], 255};
      box.extend(p.cast<double>());
    }
    std::mt19937 rng(static_cast<uint32_t>(id));
    for (size_t i = n; i > 1; --i) {
      std::swap(data[i - 1], data[std::uniform_int_distribution<size_t>(0, i - 1)(rng)]);
    }
    buffer.centre_cam = n > 0 ? Eigen::Vector3d(box.center()) : Eigen::Vector3d::Zero();
    buffer.radius = n > 0 ? 0.5 * box.diagonal().norm() : 0.0;
    gl.BindBuffer(GL_ARRAY_BUFFER, buffer.buffer);
    gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(ColorVertex)),
                  data.data(), GL_STATIC_DRAW);
    buffer.count = static_cast<GLsizei>(data.size());
    buffer.version = version;
    ++impl.uploads;
    impl.uploaded_points += data.size();
  }
  gl.BindBuffer(GL_ARRAY_BUFFER, 0);
  SIGHTMAP_CHECK(gl.GetError() == GL_NO_ERROR,
                 "OpenGL could not store the map's points (out of memory?)");
}

void MapRenderer::BeginFrame(int framebuffer_width, int framebuffer_height) {
  Impl& impl = *impl_;
  const GlApi& gl = impl.gl;
  impl.framebuffer_width = framebuffer_width;
  impl.framebuffer_height = framebuffer_height;
  gl.Disable(GL_SCISSOR_TEST);
  gl.Viewport(0, 0, framebuffer_width, framebuffer_height);
  const Eigen::Vector3f& bg = impl.options.background_rgb;
  gl.ClearColor(bg.x(), bg.y(), bg.z(), 1.0f);
  gl.ClearDepth(1.0);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.Disable(GL_LIGHTING);
  gl.Disable(GL_TEXTURE_2D);
  gl.Disable(GL_CULL_FACE);
  gl.Disable(GL_DITHER);
  gl.Disable(GL_BLEND);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
}

void MapRenderer::DrawMap(const MapScene& scene, const ViewCamera& view, const Viewport& viewport) {
  Impl& impl = *impl_;
  impl.SetViewport(viewport);
  const Eigen::Matrix4d eye_from_world = impl.SetCamera(view);
  impl.DrawPoints(scene, view, viewport, eye_from_world);
  impl.DrawWalk(scene, view, eye_from_world);
  impl.DrawCamera(scene, view);
  impl.DrawAppliances(scene, view, viewport);
  impl.gl.Disable(GL_SCISSOR_TEST);
}

void MapRenderer::DrawStatus(const MapScene& scene, const Viewport& viewport) {
  Impl& impl = *impl_;
  const MapStatus status = scene.status();
  const int scale = impl.options.text_scale;
  const int elapsed = static_cast<int>(status.elapsed_s);
  char line1[128];
  std::snprintf(line1, sizeof(line1), "keyframes %lld  loops %lld  points %s",
                static_cast<long long>(status.keyframes), static_cast<long long>(status.loops),
                FormatCount(static_cast<double>(scene.num_points())).c_str());
  char line3[96];
  std::snprintf(line3, sizeof(line3), "%.2f kf/s  elapsed %d:%02d:%02d", status.keyframes_per_s,
                elapsed / 3600, (elapsed / 60) % 60, elapsed % 60);
  const std::string line2 = std::string("state: ") + ToString(status.tracking);
  const std::string line4 =
      impl.options.show_coverage ? CoverageLine(scene, impl.options.coverage) : std::string();
  const int lines = line4.empty() ? 3 : 4;
  impl.Begin2D(viewport);
  const float x = 6.0f * scale;
  const float y = 6.0f * scale;
  const float line = static_cast<float>(kLineAdvance * scale);
  // One backing for the block, then the lines.
  std::vector<Eigen::Vector2f> rect;
  const int width = std::max({TextWidthPx(line1, scale), TextWidthPx(line2, scale),
                              TextWidthPx(line3, scale), TextWidthPx(line4, scale)});
  Impl::AppendRect(x - 2.0f * scale, y - 2.0f * scale, x + width + 2.0f * scale,
                   y + (lines - 1) * line + kGlyphHeight * scale + 2.0f * scale, &rect);
  impl.Triangles2D(rect, Eigen::Vector4f(0, 0, 0, 0.6f));
  const Eigen::Vector3f white(0.95f, 0.95f, 0.95f);
  impl.Text2D(line1, x, y, scale, white, false);
  impl.Text2D(line2, x, y + line, scale, TrackingColor(status.tracking), false);
  impl.Text2D(line3, x, y + 2 * line, scale, white, false);
  if (!line4.empty()) impl.Text2D(line4, x, y + 3 * line, scale, white, false);
  impl.gl.Disable(GL_SCISSOR_TEST);
}

void MapRenderer::DrawScaleBar(const ViewCamera& view, const Viewport& viewport) {
  if (!view.orthographic) return;
  Impl& impl = *impl_;
  const double px_per_m = view.intrinsics.fx;
  // The longest of 0.5, 1, 2, 5, 10, ... m that fits in a fifth of the viewport.
  double metres = 0.5;
  for (const double candidate : {1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0}) {
    if (candidate * px_per_m <= viewport.width / 5.0) metres = candidate;
  }
  const int scale = impl.options.text_scale;
  const float length = static_cast<float>(metres * px_per_m);
  const float x0 = 8.0f * scale;
  const float y0 = static_cast<float>(viewport.height) - 8.0f * scale;
  impl.Begin2D(viewport);
  std::vector<Eigen::Vector2f> bar;
  Impl::AppendRect(x0, y0 - scale, x0 + length, y0 + scale, &bar);
  Impl::AppendRect(x0, y0 - 4.0f * scale, x0 + scale, y0 + scale, &bar);
  Impl::AppendRect(x0 + length - scale, y0 - 4.0f * scale, x0 + length, y0 + scale, &bar);
  impl.Triangles2D(bar, Eigen::Vector4f(0.95f, 0.95f, 0.95f, 1.0f));
  char text[32];
  std::snprintf(text, sizeof(text), metres < 1.0 ? "%.1f m" : "%.0f m", metres);
  impl.Text2D(text, x0 + length + 4.0f * scale, y0 - 5.0f * scale, scale,
              Eigen::Vector3f(0.95f, 0.95f, 0.95f));
  impl.gl.Disable(GL_SCISSOR_TEST);
}

void MapRenderer::DrawText(std::string_view text, int x, int y, int scale,
                           const Eigen::Vector3f& rgb) {
  Impl& impl = *impl_;
  impl.Begin2D(impl.Whole());
  impl.Text2D(text, static_cast<float>(x), static_cast<float>(y), scale, rgb);
  impl.gl.Disable(GL_SCISSOR_TEST);
}

void MapRenderer::DrawImage(const cv::Mat& image, const Viewport& viewport) {
  if (image.empty() || viewport.width <= 0 || viewport.height <= 0) return;
  SIGHTMAP_CHECK(image.depth() == CV_8U && (image.channels() == 3 || image.channels() == 1),
                 "DrawImage takes an 8-bit BGR or grey image");
  Impl& impl = *impl_;
  const GlApi& gl = impl.gl;
  cv::Mat bgr;
  if (image.channels() == 1) {
    cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  } else {
    bgr = image.isContinuous() ? image : image.clone();
  }
  if (impl.image_texture == 0) {
    gl.GenTextures(1, &impl.image_texture);
    gl.BindTexture(GL_TEXTURE_2D, impl.image_texture);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  }
  gl.BindTexture(GL_TEXTURE_2D, impl.image_texture);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, bgr.cols, bgr.rows, 0, GL_BGR, GL_UNSIGNED_BYTE,
                bgr.data);
  // Fit, keeping the aspect ratio, centred.
  const double s = std::min(static_cast<double>(viewport.width) / bgr.cols,
                            static_cast<double>(viewport.height) / bgr.rows);
  const float w = static_cast<float>(bgr.cols * s);
  const float h = static_cast<float>(bgr.rows * s);
  const float x0 = 0.5f * (static_cast<float>(viewport.width) - w);
  const float y0 = 0.5f * (static_cast<float>(viewport.height) - h);
  impl.Begin2D(viewport);
  const Eigen::Vector2f positions[6] = {{x0, y0}, {x0 + w, y0},     {x0 + w, y0 + h},
                                        {x0, y0}, {x0 + w, y0 + h}, {x0, y0 + h}};
  const Eigen::Vector2f uvs[6] = {{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}};
  gl.Enable(GL_TEXTURE_2D);
  gl.TexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_REPLACE);
  gl.Color4f(1, 1, 1, 1);
  gl.EnableClientState(GL_VERTEX_ARRAY);
  gl.EnableClientState(GL_TEXTURE_COORD_ARRAY);
  gl.VertexPointer(2, GL_FLOAT, sizeof(Eigen::Vector2f), positions);
  gl.TexCoordPointer(2, GL_FLOAT, sizeof(Eigen::Vector2f), uvs);
  gl.DrawArrays(GL_TRIANGLES, 0, 6);
  gl.DisableClientState(GL_TEXTURE_COORD_ARRAY);
  gl.DisableClientState(GL_VERTEX_ARRAY);
  gl.Disable(GL_TEXTURE_2D);
  gl.Disable(GL_SCISSOR_TEST);
}

void MapRenderer::DrawProgress(const MapScene& scene, int width, int height) {
  Impl& impl = *impl_;
  Sync(scene);
  BeginFrame(width, height);
  const ProgressLayout layout = MakeProgressLayout(scene, width, height, impl.options);
  DrawMap(scene, layout.top_down, layout.top_down_viewport);
  DrawMap(scene, layout.follow, layout.follow_viewport);
  DrawScaleBar(layout.top_down, layout.top_down_viewport);
  DrawStatus(scene, layout.top_down_viewport);
  // A divider and the panel titles.
  impl.Begin2D(impl.Whole());
  std::vector<Eigen::Vector2f> divider;
  const float x = static_cast<float>(layout.follow_viewport.x);
  Impl::AppendRect(x - 1.0f, 0.0f, x + 1.0f, static_cast<float>(height), &divider);
  impl.Triangles2D(divider, Eigen::Vector4f(0.5f, 0.5f, 0.55f, 1.0f));
  const int scale = impl.options.text_scale;
  const Eigen::Vector3f grey(0.8f, 0.8f, 0.85f);
  const char* kTopTitle = "FLOOR PLAN";
  const char* kFollowTitle = "CAMERA VIEW";
  impl.Text2D(kTopTitle,
              static_cast<float>(layout.top_down_viewport.width - TextWidthPx(kTopTitle, scale) -
                                 6 * scale),
              6.0f * scale, scale, grey);
  impl.Text2D(kFollowTitle, x + 6.0f * scale, 6.0f * scale, scale, grey);
  impl.gl.Disable(GL_SCISSOR_TEST);
}

cv::Mat MapRenderer::ReadImage(int width, int height) {
  const GlApi& gl = impl_->gl;
  gl.Finish();
  cv::Mat bgr(height, width, CV_8UC3);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, width, height, GL_BGR, GL_UNSIGNED_BYTE, bgr.data);
  SIGHTMAP_CHECK(gl.GetError() == GL_NO_ERROR, "OpenGL failed to read back the rendered image");
  cv::flip(bgr, bgr, 0);  // GL rows start at the bottom
  return bgr;
}

}  // namespace sightmap::render
