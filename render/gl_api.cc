#include "render/gl_api.h"

#include <GL/osmesa.h>

#include "core/check.h"

namespace sightmap::render {

void GlApi::Load(GlProcLoader loader) {
  SIGHTMAP_CHECK(loader != nullptr, "no GL loader given");
#define SIGHTMAP_GL_LOAD(name)                                                             \
  {                                                                                        \
    const GlProc proc = loader("gl" #name);                                                \
    SIGHTMAP_CHECK(proc != nullptr, "the OpenGL implementation has no gl" #name            \
                                    ": render/ needs OpenGL 1.5 (compatibility profile)"); \
    name = reinterpret_cast<decltype(name)>(proc);                                         \
  }
#define SIGHTMAP_GL_LOAD_TYPED(name, type) SIGHTMAP_GL_LOAD(name)
  SIGHTMAP_GL_FUNCTIONS(SIGHTMAP_GL_LOAD, SIGHTMAP_GL_LOAD_TYPED)
#undef SIGHTMAP_GL_LOAD_TYPED
#undef SIGHTMAP_GL_LOAD
}

namespace {
GlProc OsMesaLoader(const char* name) { return OSMesaGetProcAddress(name); }
}  // namespace

const GlApi& OsMesaGl() {
  static const GlApi api = [] {
    GlApi table;
    table.Load(&OsMesaLoader);
    return table;
  }();
  return api;
}

}  // namespace sightmap::render
