// How render/ reaches OpenGL: every entry point is looked up through the current context's own
// GetProcAddress (OSMesaGetProcAddress for the off-screen context, glfwGetProcAddress for the
// preview window), never through the linker.
//
// Why: libOSMesa and libGL (glvnd) both export glClear, glDrawArrays, ... When a binary links both
// (the `sightmap` binary has the off-screen writer and the GLFW window), each direct call binds to
// whichever library comes first in the link order. With libGL first, every GL call made on an
// OSMesa context goes to glvnd's dispatch, which knows no OSMesa context, and silently does
// nothing: black images, no error. (Measured on Debian 12 / Mesa 22.3.6 with a test program.)
// Loading through each context's loader works in any link order and with any vendor's libGL.
#pragma once

namespace sightmap::render {

using GlProc = void (*)();
// Returns the entry point `name` ("glClear") of the GL implementation behind a context, or null.
using GlProcLoader = GlProc (*)(const char* name);

}  // namespace sightmap::render
