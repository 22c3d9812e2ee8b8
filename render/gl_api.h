// The OpenGL entry points render/ uses, as a table of function pointers filled by a context's
// loader (see gl_proc.h for why no GL function is called through the linker). Internal to render/:
// only .cc files include it, public headers stay free of GL.
//
// Call sites read `gl.Clear(GL_COLOR_BUFFER_BIT)`: the member names drop the "gl" prefix, so a
// direct glClear(...) stands out in review, and render_gl_symbols_test fails the build's tests if
// any object file of render/ references a gl* symbol.
#pragma once

#include <GL/gl.h>
#include <GL/glext.h>

#include "render/gl_proc.h"

namespace sightmap::render {

// Legacy (compatibility profile) GL 1.x, declared by GL/gl.h (X: the type is taken from that
// declaration, nothing is linked by name), plus the GL 1.5 buffer objects (T: glext.h's types).
#define SIGHTMAP_GL_FUNCTIONS(X, T)        \
  X(Enable)                                \
  X(Disable)                               \
  X(Viewport)                              \
  X(Scissor)                               \
  X(ClearColor)                            \
  X(ClearDepth)                            \
  X(Clear)                                 \
  X(DepthFunc)                             \
  X(DepthMask)                             \
  X(PixelStorei)                           \
  X(MatrixMode)                            \
  X(LoadMatrixd)                           \
  X(LoadIdentity)                          \
  X(EnableClientState)                     \
  X(DisableClientState)                    \
  X(VertexPointer)                         \
  X(ColorPointer)                          \
  X(NormalPointer)                         \
  X(TexCoordPointer)                       \
  X(DrawArrays)                            \
  X(ShadeModel)                            \
  X(LightModelfv)                          \
  X(LightModeli)                           \
  X(Lightfv)                               \
  X(Materialfv)                            \
  X(ColorMaterial)                         \
  X(TexEnvi)                               \
  X(Color4f)                               \
  X(Color4ub)                              \
  X(BindTexture)                           \
  X(GenTextures)                           \
  X(DeleteTextures)                        \
  X(TexParameteri)                         \
  X(TexImage2D)                            \
  X(GetError)                              \
  X(Finish)                                \
  X(ReadPixels)                            \
  X(GetString)                             \
  X(PointSize)                             \
  X(LineWidth)                             \
  T(GenBuffers, PFNGLGENBUFFERSPROC)       \
  T(DeleteBuffers, PFNGLDELETEBUFFERSPROC) \
  T(BindBuffer, PFNGLBINDBUFFERPROC)       \
  T(BufferData, PFNGLBUFFERDATAPROC)       \
  X(BlendFunc)                             \
  X(Fogi)                                  \
  X(Fogf)                                  \
  X(Fogfv)                                 \
  X(Hint)                                  \
  X(GetIntegerv)

struct GlApi {
#define SIGHTMAP_GL_DECLARE(name) decltype(&::gl##name) name = nullptr;
#define SIGHTMAP_GL_DECLARE_TYPED(name, type) type name = nullptr;
  SIGHTMAP_GL_FUNCTIONS(SIGHTMAP_GL_DECLARE, SIGHTMAP_GL_DECLARE_TYPED)
#undef SIGHTMAP_GL_DECLARE_TYPED
#undef SIGHTMAP_GL_DECLARE

  // Fills every entry through `loader`; throws sightmap::Error naming the first missing one.
  void Load(GlProcLoader loader);
};

// The table for OSMesa contexts, loaded once (thread-safe); valid on any thread whose current
// context is an OSMesa context.
const GlApi& OsMesaGl();

}  // namespace sightmap::render
