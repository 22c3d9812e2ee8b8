// An off-screen OpenGL context (OSMesa, software rendering, no display or GPU needed).
//
// The context owns its colour buffer (RGBA, 8 bit per channel) and a 24-bit depth buffer. It uses
// the legacy fixed-function pipeline (OpenGL 1.x/2.x compatibility profile), which every OSMesa
// build provides. One context can be reused for any number of renders and resized between them,
// so the simulator and the progress-image writer keep one each instead of re-creating it.
//
// OSMesa contexts are bound to the calling thread: create, use and destroy a context on one thread.
#pragma once

#include <memory>
#include <string>

#include "render/gl_proc.h"

namespace sightmap::render {

class OffscreenContext {
 public:
  // Throws sightmap::Error when OSMesa cannot create a context (e.g. out of memory).
  OffscreenContext(int width, int height);
  ~OffscreenContext();
  OffscreenContext(const OffscreenContext&) = delete;
  OffscreenContext& operator=(const OffscreenContext&) = delete;

  // Binds the context and its buffer to the calling thread; every GL call goes to this context
  // until another context is made current.
  void MakeCurrent();
  // Reallocates the buffer at another size [px] (a no-op when it is unchanged) and makes the
  // context current.
  void Resize(int width, int height);

  // The OSMesa entry point `name` (for GlProcLoader users such as MapRenderer); any thread.
  static GlProc ProcAddress(const char* name);

  int width() const;
  int height() const;
  // GL_VERSION and GL_RENDERER of this context, e.g. "4.5 (Compatibility Profile) Mesa 22.3.6".
  std::string GlVersion() const;
  std::string GlRenderer() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::render
