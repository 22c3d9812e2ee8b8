#include "capture/openni_runtime.h"

#include <mutex>

#include <OpenNI.h>

#include "core/check.h"

namespace sightmap::capture {
namespace {
std::mutex g_mutex;
std::weak_ptr<OpenNiRuntime> g_runtime;
}  // namespace

std::shared_ptr<OpenNiRuntime> OpenNiRuntime::Acquire() {
  std::lock_guard<std::mutex> lock(g_mutex);
  if (auto runtime = g_runtime.lock()) return runtime;
  if (openni::OpenNI::initialize() != openni::STATUS_OK) {
    SIGHTMAP_THROW(Error, "OpenNI2 failed to initialise: " << openni::OpenNI::getExtendedError()
                                                           << " — reinstall libopenni2-0");
  }
  std::shared_ptr<OpenNiRuntime> runtime(new OpenNiRuntime());
  g_runtime = runtime;
  return runtime;
}

OpenNiRuntime::~OpenNiRuntime() {
  // Called with g_runtime already expired; a concurrent Acquire() would re-initialise after this.
  std::lock_guard<std::mutex> lock(g_mutex);
  openni::OpenNI::shutdown();
}

}  // namespace sightmap::capture
