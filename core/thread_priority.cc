#include "core/thread_priority.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

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

int LowerThreadsNamed(const std::string& name_prefix, int nice) {
  const int target = std::min(19, nice);
  int changed = 0;
  std::error_code error;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task", error)) {
    std::string name;
    std::getline(std::ifstream(task.path() / "comm"), name);
    if (name.rfind(name_prefix, 0) != 0) continue;
    id_t tid = 0;
    try {
      tid = static_cast<id_t>(std::stoul(task.path().filename().string()));
    } catch (const std::exception&) {
      continue;
    }
    errno = 0;
    const int now = getpriority(PRIO_PROCESS, tid);
    if (errno != 0 || now >= target) continue;
    if (setpriority(PRIO_PROCESS, tid, target) == 0) ++changed;
  }
  return changed;
}

}  // namespace sightmap
