#include "core/thread_priority.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include <opencv2/core/utility.hpp>

namespace sightmap {
namespace {

id_t ThisThread() { return static_cast<id_t>(syscall(SYS_gettid)); }

}  // namespace

int ThisThreadsNice() {
  errno = 0;
  const int nice = getpriority(PRIO_PROCESS, ThisThread());
  return errno == 0 ? nice : 0;
}

bool LowerThisThreadsPriority(int increment) {
  if (increment <= 0) return true;
  // Started by a lowered thread, the workers would run every stage's parallel work lowered.
  cv::parallel_for_(cv::Range(0, std::max(2, cv::getNumThreads())), [](const cv::Range&) {});
  const int target = std::min(19, ThisThreadsNice() + increment);
  return setpriority(PRIO_PROCESS, ThisThread(), target) == 0;
}

}  // namespace sightmap
