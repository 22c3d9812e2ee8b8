// Draws textured triangle meshes (boxes, mostly) from a pinhole camera and reads back colour,
// metric depth and an object-ID buffer. Used by the synthetic building (sim/) and progress images.
//
// Conventions: world points in metres; the camera is given as world_from_cam with the OpenCV
// camera frame (x right, y down, z forward) and sightmap Intrinsics (pixel centres at integer
// coordinates). The renderer converts to OpenGL's frame (y up, z backward) internally and builds
// the projection from fx, fy, cx, cy, so a world point lands exactly where Intrinsics::Project
// puts it. Read-back images are top row first, like every cv::Mat.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "render/offscreen_context.h"

namespace sightmap::render {

struct Material {
  Eigen::Vector3f color_rgb = Eigen::Vector3f(0.8f, 0.8f, 0.8f);  // [0, 1]; multiplies the texture
  int texture = -1;  // a handle from MeshRenderer::AddTexture; -1 = plain colour
  // Metres per texture repeat on each face (wallpaper, carpet); 0 stretches the image once over
  // each face (posters, screens).
  float texture_scale_m = 0.0f;
  // The surface returns no depth to an active IR sensor (glass, glossy screens); reported in
  // RenderedView::no_depth so the sensor model can drop it.
  bool no_depth = false;
  // Emissive (ceiling lights, screens): drawn at full colour regardless of the lights.
  bool unlit = false;
};

// Triangles with per-vertex normals and texture coordinates, one material, and an object ID
// (0 = background geometry such as walls; > 0 = an object the ID buffer reports).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions;  // world [m], three per triangle
  std::vector<Eigen::Vector3f> normals;    // unit, outward
  std::vector<Eigen::Vector2f> uvs;        // texture coordinates, (0, 0) = image top-left
  Material material;
  int id = 0;
};

// An axis-aligned box rotated by `yaw_rad` about the world z axis (z is up) around its centre;
// `size` = extent along the box's own x, y, z [m]. Faces carry the material's texture upright.
TriangleMesh MakeBox(const Eigen::Vector3f& center, const Eigen::Vector3f& size, float yaw_rad,
                     const Material& material, int id = 0);

struct DirectionalLight {
  Eigen::Vector3f direction_to_light = Eigen::Vector3f(0.3f, 0.2f, 1.0f);  // world, any length
  float intensity = 0.5f;                                                  // diffuse, [0, 1]
};

struct RenderOptions {
  double near_m = 0.05;  // clipping planes [m]; depth precision depends on far / near
  double far_m = 30.0;
  float ambient = 0.5f;  // ambient light [0, 1]
  std::vector<DirectionalLight> lights = {DirectionalLight()};
  Eigen::Vector3f background_rgb = Eigen::Vector3f(0, 0, 0);  // [0, 1]

  bool Check(std::string* error) const;
};

struct RenderedView {
  cv::Mat color;     // CV_8UC3, BGR
  cv::Mat depth;     // CV_32F, distance along the optical axis (camera z) [m]; 0 = nothing drawn
  cv::Mat no_depth;  // CV_8U, 255 where the visible surface has Material::no_depth
};

class MeshRenderer {
 public:
  // Creates its own off-screen context; it is resized to each call's image size.
  explicit MeshRenderer(const RenderOptions& options = RenderOptions());
  ~MeshRenderer();
  MeshRenderer(const MeshRenderer&) = delete;
  MeshRenderer& operator=(const MeshRenderer&) = delete;

  // Uploads an 8-bit BGR (or grey) image as a mipmapped, repeating texture; returns its handle.
  int AddTexture(const cv::Mat& image);
  void AddMesh(TriangleMesh mesh);
  // Removes every mesh (textures stay).
  void ClearMeshes();
  // Removes every texture and every mesh (which may refer to them), freeing their memory: a
  // caller drawing a stream of different images keeps the renderer's memory bounded. Handles
  // start again from 0.
  void ClearTextures();
  size_t num_textures() const;
  size_t num_meshes() const;

  void set_options(const RenderOptions& options);
  const RenderOptions& options() const;

  // Lit, textured colour plus depth and the no-depth mask.
  RenderedView Render(const Intrinsics& intrinsics, const Eigen::Isometry3d& world_from_cam);

  // Object IDs (CV_32S; 0 = background or nothing) with every mesh occluding, no lighting or
  // texture. With only_id > 0, only the meshes of that ID are drawn (its unoccluded footprint).
  cv::Mat RenderIds(const Intrinsics& intrinsics, const Eigen::Isometry3d& world_from_cam,
                    int only_id = 0);

  OffscreenContext& context();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::render
