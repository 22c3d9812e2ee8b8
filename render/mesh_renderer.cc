#include "render/mesh_renderer.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "render/gl_api.h"
#include "render/gl_camera.h"

namespace sightmap::render {
namespace {

// One face as seen from outside: corners bottom-left, bottom-right, top-right, top-left.
void AddQuad(const Eigen::Vector3f& bl, const Eigen::Vector3f& br, const Eigen::Vector3f& tr,
             const Eigen::Vector3f& tl, const Eigen::Vector3f& normal, float width_m,
             float height_m, float texture_scale_m, TriangleMesh* mesh) {
  float u1 = 1.0f;
  float v1 = 1.0f;
  if (texture_scale_m > 0.0f) {
    u1 = width_m / texture_scale_m;
    v1 = height_m / texture_scale_m;
  }
  // Texture row 0 (the image top) at the face's top edge.
  const Eigen::Vector2f uv_bl(0, v1), uv_br(u1, v1), uv_tr(u1, 0), uv_tl(0, 0);
  const Eigen::Vector3f corners[6] = {bl, br, tr, bl, tr, tl};
  const Eigen::Vector2f uvs[6] = {uv_bl, uv_br, uv_tr, uv_bl, uv_tr, uv_tl};
  for (int i = 0; i < 6; ++i) {
    mesh->positions.push_back(corners[i]);
    mesh->normals.push_back(normal);
    mesh->uvs.push_back(uvs[i]);
  }
}

}  // namespace

TriangleMesh MakeBox(const Eigen::Vector3f& center, const Eigen::Vector3f& size, float yaw_rad,
                     const Material& material, int id) {
  TriangleMesh mesh;
  mesh.material = material;
  mesh.id = id;
  const Eigen::Matrix3f rotation =
      Eigen::AngleAxisf(yaw_rad, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f h = 0.5f * size;
  auto corner = [&](float sx, float sy, float sz) -> Eigen::Vector3f {
    return center + rotation * Eigen::Vector3f(sx * h.x(), sy * h.y(), sz * h.z());
  };
  auto axis = [&](int i, float sign) -> Eigen::Vector3f { return sign * rotation.col(i); };
  const float s = material.texture_scale_m;
  // +x face, seen from +x: right is +y.
  AddQuad(corner(1, -1, -1), corner(1, 1, -1), corner(1, 1, 1), corner(1, -1, 1), axis(0, 1),
          size.y(), size.z(), s, &mesh);
  // -x face: right is -y.
  AddQuad(corner(-1, 1, -1), corner(-1, -1, -1), corner(-1, -1, 1), corner(-1, 1, 1), axis(0, -1),
          size.y(), size.z(), s, &mesh);
  // +y face: right is -x.
  AddQuad(corner(1, 1, -1), corner(-1, 1, -1), corner(-1, 1, 1), corner(1, 1, 1), axis(1, 1),
          size.x(), size.z(), s, &mesh);
  // -y face: right is +x.
  AddQuad(corner(-1, -1, -1), corner(1, -1, -1), corner(1, -1, 1), corner(-1, -1, 1), axis(1, -1),
          size.x(), size.z(), s, &mesh);
  // Top (+z), seen from above with +y up in the image.
  AddQuad(corner(-1, -1, 1), corner(1, -1, 1), corner(1, 1, 1), corner(-1, 1, 1), axis(2, 1),
          size.x(), size.y(), s, &mesh);
  // Bottom (-z), seen from below.
  AddQuad(corner(-1, 1, -1), corner(1, 1, -1), corner(1, -1, -1), corner(-1, -1, -1), axis(2, -1),
          size.x(), size.y(), s, &mesh);
  return mesh;
}

bool RenderOptions::Check(std::string* error) const {
  if (!(near_m > 0.0 && far_m > near_m)) {
    *error = "need 0 < near_m < far_m";
    return false;
  }
  if (ambient < 0.0f || ambient > 1.0f) {
    *error = "ambient must be in [0, 1]";
    return false;
  }
  for (const DirectionalLight& light : lights) {
    if (light.direction_to_light.norm() <= 0.0f || light.intensity < 0.0f) {
      *error = "each light needs a non-zero direction and a non-negative intensity";
      return false;
    }
  }
  if (lights.size() > 8) {
    *error = "at most 8 lights (the fixed-function pipeline's minimum)";
    return false;
  }
  return true;
}

struct MeshRenderer::Impl {
  explicit Impl(const RenderOptions& render_options) : context(64, 64), options(render_options) {}

  OffscreenContext context;
  RenderOptions options;
  std::vector<TriangleMesh> meshes;
  std::vector<GLuint> textures;
  const GlApi& gl = OsMesaGl();

  void Prepare(const Intrinsics& k, const Eigen::Isometry3d& world_from_cam,
               const Eigen::Vector3f& clear_rgb) {
    std::string error;
    SIGHTMAP_CHECK(k.Check(&error), "cannot render with invalid intrinsics: " << error);
    context.Resize(k.width, k.height);
    gl.Viewport(0, 0, k.width, k.height);
    gl.ClearColor(clear_rgb.x(), clear_rgb.y(), clear_rgb.z(), 1.0f);
    gl.ClearDepth(1.0);
    gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);
    gl.Disable(GL_DITHER);
    gl.Disable(GL_BLEND);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);

    const Eigen::Matrix4d projection = GlPerspective(k, options.near_m, options.far_m);
    gl.MatrixMode(GL_PROJECTION);
    gl.LoadMatrixd(projection.data());  // Eigen is column-major like GL
    const Eigen::Matrix4d gl_eye_from_world = GlEyeFromCam() * world_from_cam.inverse().matrix();
    gl.MatrixMode(GL_MODELVIEW);
    gl.LoadMatrixd(gl_eye_from_world.data());
  }

  void Draw(const TriangleMesh& mesh) {
    if (mesh.positions.empty()) return;
    gl.EnableClientState(GL_VERTEX_ARRAY);
    gl.VertexPointer(3, GL_FLOAT, sizeof(Eigen::Vector3f), mesh.positions.data());
    gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(mesh.positions.size()));
    gl.DisableClientState(GL_VERTEX_ARRAY);
  }

  // Converts a window depth in [0, 1] to the distance along the optical axis [m].
  float MetricDepth(float window_depth) const {
    if (window_depth >= 1.0f) return 0.0f;
    const double n = options.near_m;
    const double f = options.far_m;
    const double ndc = 2.0 * window_depth - 1.0;
    return static_cast<float>(2.0 * f * n / ((f + n) - ndc * (f - n)));
  }

  // The rendered colour and metric depth, and the no-depth mask (alpha below half where a
  // material has no depth), rows top first.
  RenderedView ReadBack(const Intrinsics& intrinsics) const {
    gl.Finish();
    const int w = intrinsics.width;
    const int h = intrinsics.height;
    cv::Mat bgra(h, w, CV_8UC4);
    gl.ReadPixels(0, 0, w, h, GL_BGRA, GL_UNSIGNED_BYTE, bgra.data);
    cv::Mat window_depth(h, w, CV_32F);
    gl.ReadPixels(0, 0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, window_depth.data);
    SIGHTMAP_CHECK(gl.GetError() == GL_NO_ERROR, "OpenGL failed to read back the rendered image");

    // GL rows start at the bottom.
    cv::flip(bgra, bgra, 0);
    cv::flip(window_depth, window_depth, 0);
    RenderedView view;
    view.color.create(h, w, CV_8UC3);
    view.no_depth.create(h, w, CV_8U);
    view.depth.create(h, w, CV_32F);
    for (int v = 0; v < h; ++v) {
      const cv::Vec4b* in = bgra.ptr<cv::Vec4b>(v);
      const float* wd = window_depth.ptr<float>(v);
      cv::Vec3b* out = view.color.ptr<cv::Vec3b>(v);
      uint8_t* mask = view.no_depth.ptr<uint8_t>(v);
      float* depth = view.depth.ptr<float>(v);
      for (int u = 0; u < w; ++u) {
        out[u] = cv::Vec3b(in[u][0], in[u][1], in[u][2]);
        depth[u] = MetricDepth(wd[u]);
        mask[u] = (depth[u] > 0.0f && in[u][3] < 128) ? 255 : 0;
      }
    }
    return view;
  }
};

MeshRenderer::MeshRenderer(const RenderOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_ = std::make_unique<Impl>(options);
}

MeshRenderer::~MeshRenderer() {
  if (impl_ && !impl_->textures.empty()) {
    const GlApi& gl = impl_->gl;
    impl_->context.MakeCurrent();
    gl.DeleteTextures(static_cast<GLsizei>(impl_->textures.size()), impl_->textures.data());
  }
}

int MeshRenderer::AddTexture(const cv::Mat& image) {
  SIGHTMAP_CHECK(
      !image.empty() && image.depth() == CV_8U && (image.channels() == 3 || image.channels() == 1),
      "a texture must be a non-empty 8-bit BGR or grey image");
  cv::Mat bgr;
  if (image.channels() == 1) {
    cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  } else {
    bgr = image.isContinuous() ? image : image.clone();
  }
  impl_->context.MakeCurrent();
  const GlApi& gl = impl_->gl;
  GLuint name = 0;
  gl.GenTextures(1, &name);
  gl.BindTexture(GL_TEXTURE_2D, name);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  // Mipmaps keep distant posters from aliasing into noise that real optics would blur away.
  gl.TexParameteri(GL_TEXTURE_2D, GL_GENERATE_MIPMAP, GL_TRUE);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, bgr.cols, bgr.rows, 0, GL_BGR, GL_UNSIGNED_BYTE,
                bgr.data);
  SIGHTMAP_CHECK(gl.GetError() == GL_NO_ERROR,
                 "OpenGL rejected a " << bgr.cols << "x" << bgr.rows << " texture");
  impl_->textures.push_back(name);
  return static_cast<int>(impl_->textures.size()) - 1;
}

void MeshRenderer::AddMesh(TriangleMesh mesh) {
  SIGHTMAP_CHECK(mesh.positions.size() % 3 == 0 && mesh.normals.size() == mesh.positions.size() &&
                     mesh.uvs.size() == mesh.positions.size(),
                 "a mesh needs three vertices per triangle, each with a normal and a uv");
  SIGHTMAP_CHECK(mesh.material.texture < static_cast<int>(impl_->textures.size()),
                 "mesh refers to texture " << mesh.material.texture << " which was never added");
  SIGHTMAP_CHECK(mesh.id >= 0 && mesh.id < (1 << 24), "mesh ids must be in [0, 2^24)");
  impl_->meshes.push_back(std::move(mesh));
}

void MeshRenderer::ClearMeshes() { impl_->meshes.clear(); }

void MeshRenderer::ClearTextures() {
  impl_->meshes.clear();
  if (impl_->textures.empty()) return;
  impl_->context.MakeCurrent();
  impl_->gl.DeleteTextures(static_cast<GLsizei>(impl_->textures.size()), impl_->textures.data());
  impl_->textures.clear();
}
size_t MeshRenderer::num_textures() const { return impl_->textures.size(); }
size_t MeshRenderer::num_meshes() const { return impl_->meshes.size(); }

void MeshRenderer::set_options(const RenderOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_->options = options;
}
const RenderOptions& MeshRenderer::options() const { return impl_->options; }
OffscreenContext& MeshRenderer::context() { return impl_->context; }

namespace {

// The fixed-function lighting of RenderOptions: an ambient term and directional lights given in
// world coordinates (set with the world-to-eye modelview loaded), lit on both sides, the
// materials' colour as ambient and diffuse, no specular.
void SetUpLighting(const GlApi& gl, const RenderOptions& options) {
  gl.Enable(GL_NORMALIZE);
  gl.ShadeModel(GL_SMOOTH);
  const GLfloat ambient[4] = {options.ambient, options.ambient, options.ambient, 1.0f};
  gl.LightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
  gl.LightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  for (int i = 0; i < 8; ++i) gl.Disable(GL_LIGHT0 + i);
  for (size_t i = 0; i < options.lights.size(); ++i) {
    const DirectionalLight& light = options.lights[i];
    const Eigen::Vector3f d = light.direction_to_light.normalized();
    const GLfloat position[4] = {d.x(), d.y(), d.z(), 0.0f};
    const GLfloat diffuse[4] = {light.intensity, light.intensity, light.intensity, 1.0f};
    const GLfloat zero[4] = {0, 0, 0, 1};
    const GLenum id = GL_LIGHT0 + static_cast<GLenum>(i);
    gl.Lightfv(id, GL_POSITION, position);
    gl.Lightfv(id, GL_DIFFUSE, diffuse);
    gl.Lightfv(id, GL_AMBIENT, zero);
    gl.Lightfv(id, GL_SPECULAR, zero);
    gl.Enable(id);
  }
  const GLfloat zero[4] = {0, 0, 0, 1};
  gl.Materialfv(GL_FRONT_AND_BACK, GL_SPECULAR, zero);
  gl.Materialfv(GL_FRONT_AND_BACK, GL_EMISSION, zero);
  gl.ColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
  gl.Enable(GL_COLOR_MATERIAL);
  gl.TexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
}

// Each mesh with its material: colour (alpha carries the no-depth flag), lighting, texture.
void DrawMeshes(const GlApi& gl, const std::vector<TriangleMesh>& meshes,
                const std::vector<GLuint>& textures) {
  gl.EnableClientState(GL_VERTEX_ARRAY);
  gl.EnableClientState(GL_NORMAL_ARRAY);
  for (const TriangleMesh& mesh : meshes) {
    if (mesh.positions.empty()) continue;
    const Material& m = mesh.material;
    // Alpha carries the no-depth flag to the read-back (blending is off, so it is stored as is).
    const float alpha = m.no_depth ? 0.0f : 1.0f;
    gl.Color4f(m.color_rgb.x(), m.color_rgb.y(), m.color_rgb.z(), alpha);
    if (m.unlit) {
      gl.Disable(GL_LIGHTING);
    } else {
      gl.Enable(GL_LIGHTING);
    }
    if (m.texture >= 0) {
      gl.Enable(GL_TEXTURE_2D);
      gl.BindTexture(GL_TEXTURE_2D, textures[static_cast<size_t>(m.texture)]);
      gl.EnableClientState(GL_TEXTURE_COORD_ARRAY);
      gl.TexCoordPointer(2, GL_FLOAT, sizeof(Eigen::Vector2f), mesh.uvs.data());
    } else {
      gl.Disable(GL_TEXTURE_2D);
      gl.DisableClientState(GL_TEXTURE_COORD_ARRAY);
    }
    gl.VertexPointer(3, GL_FLOAT, sizeof(Eigen::Vector3f), mesh.positions.data());
    gl.NormalPointer(GL_FLOAT, sizeof(Eigen::Vector3f), mesh.normals.data());
    gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(mesh.positions.size()));
  }
  gl.DisableClientState(GL_TEXTURE_COORD_ARRAY);
  gl.DisableClientState(GL_NORMAL_ARRAY);
  gl.DisableClientState(GL_VERTEX_ARRAY);
  gl.Disable(GL_TEXTURE_2D);
  gl.Disable(GL_LIGHTING);
  gl.Disable(GL_COLOR_MATERIAL);
}

}  // namespace

RenderedView MeshRenderer::Render(const Intrinsics& intrinsics,
                                  const Eigen::Isometry3d& world_from_cam) {
  Impl& impl = *impl_;
  const GlApi& gl = impl.gl;
  impl.Prepare(intrinsics, world_from_cam, impl.options.background_rgb);
  SetUpLighting(gl, impl.options);
  DrawMeshes(gl, impl.meshes, impl.textures);
  return impl.ReadBack(intrinsics);
}

cv::Mat MeshRenderer::RenderIds(const Intrinsics& intrinsics,
                                const Eigen::Isometry3d& world_from_cam, int only_id) {
  Impl& impl = *impl_;
  const GlApi& gl = impl.gl;
  impl.Prepare(intrinsics, world_from_cam, Eigen::Vector3f::Zero());
  gl.Disable(GL_LIGHTING);
  gl.Disable(GL_TEXTURE_2D);
  gl.ShadeModel(GL_FLAT);
  for (const TriangleMesh& mesh : impl.meshes) {
    if (only_id > 0 && mesh.id != only_id) continue;
    // The ID as exact 8-bit channels: 24 bits in RGB.
    gl.Color4ub(static_cast<GLubyte>(mesh.id & 0xff), static_cast<GLubyte>((mesh.id >> 8) & 0xff),
                static_cast<GLubyte>((mesh.id >> 16) & 0xff), 255);
    impl.Draw(mesh);
  }
  gl.Finish();
  const int w = intrinsics.width;
  const int h = intrinsics.height;
  cv::Mat rgba(h, w, CV_8UC4);
  gl.ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data);
  SIGHTMAP_CHECK(gl.GetError() == GL_NO_ERROR, "OpenGL failed to read back the ID buffer");
  cv::flip(rgba, rgba, 0);
  cv::Mat ids(h, w, CV_32S);
  for (int v = 0; v < h; ++v) {
    const cv::Vec4b* in = rgba.ptr<cv::Vec4b>(v);
    int32_t* out = ids.ptr<int32_t>(v);
    for (int u = 0; u < w; ++u) out[u] = in[u][0] | (in[u][1] << 8) | (in[u][2] << 16);
  }
  return ids;
}

}  // namespace sightmap::render
