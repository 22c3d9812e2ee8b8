// OpenNI2's initialize/shutdown are process-wide; this keeps them balanced across every user in the
// process (sources, device listing). Private to capture/.
#pragma once

#include <memory>

namespace sightmap::capture {

// Holding a handle keeps OpenNI2 initialised; the last handle shuts it down. Acquire() throws
// sightmap::Error when OpenNI2 cannot initialise (e.g. its drivers folder is missing).
class OpenNiRuntime {
 public:
  static std::shared_ptr<OpenNiRuntime> Acquire();
  ~OpenNiRuntime();
  OpenNiRuntime(const OpenNiRuntime&) = delete;
  OpenNiRuntime& operator=(const OpenNiRuntime&) = delete;

 private:
  OpenNiRuntime() = default;
};

}  // namespace sightmap::capture
