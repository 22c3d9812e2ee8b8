#include "core/peak_memory.h"

#include <sys/resource.h>

namespace sightmap {

double PeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB on Linux
}

}  // namespace sightmap
