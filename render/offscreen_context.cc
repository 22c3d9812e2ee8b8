#include "render/offscreen_context.h"

#include <GL/osmesa.h>

#include <vector>

#include "core/check.h"
#include "render/gl_api.h"

namespace sightmap::render {

struct OffscreenContext::Impl {
  OSMesaContext context = nullptr;
  std::vector<unsigned char> buffer;  // RGBA, width * height * 4 bytes
  int width = 0;
  int height = 0;
};

OffscreenContext::OffscreenContext(int width, int height) : impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK(width > 0 && height > 0,
                 "off-screen context size must be positive, got " << width << "x" << height);
  // RGBA with a 24-bit depth buffer and no stencil or accumulation buffer.
  impl_->context = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
  SIGHTMAP_CHECK(impl_->context != nullptr,
                 "OSMesa could not create an off-screen GL context: check that libosmesa6 is "
                 "installed (apt-get install libosmesa6)");
  Resize(width, height);
}

OffscreenContext::~OffscreenContext() {
  if (impl_ && impl_->context != nullptr) OSMesaDestroyContext(impl_->context);
}

void OffscreenContext::MakeCurrent() {
  const bool ok = OSMesaMakeCurrent(impl_->context, impl_->buffer.data(), GL_UNSIGNED_BYTE,
                                    impl_->width, impl_->height) == GL_TRUE;
  SIGHTMAP_CHECK(ok, "OSMesa could not bind a " << impl_->width << "x" << impl_->height
                                                << " buffer to the off-screen context");
}

void OffscreenContext::Resize(int width, int height) {
  SIGHTMAP_CHECK(width > 0 && height > 0,
                 "off-screen context size must be positive, got " << width << "x" << height);
  if (width != impl_->width || height != impl_->height) {
    impl_->width = width;
    impl_->height = height;
    impl_->buffer.assign(static_cast<size_t>(width) * height * 4, 0);
  }
  MakeCurrent();
}

GlProc OffscreenContext::ProcAddress(const char* name) { return OSMesaGetProcAddress(name); }

int OffscreenContext::width() const { return impl_->width; }
int OffscreenContext::height() const { return impl_->height; }

std::string OffscreenContext::GlVersion() const {
  const auto* text = OsMesaGl().GetString(GL_VERSION);
  return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text));
}

std::string OffscreenContext::GlRenderer() const {
  const auto* text = OsMesaGl().GetString(GL_RENDERER);
  return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text));
}

}  // namespace sightmap::render
