// Thread priorities on Linux, where nice values are per thread: a pipeline stage whose work can
// wait (off-screen rendering of progress images, a replay's frame decoding) runs at a lower
// priority than the stages whose latency the user sees.
#pragma once

#include <string>

namespace sightmap {

// Raises the calling thread's nice value by `increment` (capped at 19), which lowers its share of
// a busy CPU. Best effort: returns false when the system refused (the thread then competes at its
// old priority, which only costs latency elsewhere). Threads it starts afterwards inherit it, so
// OpenCV's worker threads, which the first cv::parallel_for_ of the process starts and every
// thread's parallel work shares, are started first, at the old priority.
bool LowerThisThreadsPriority(int increment);

// The calling thread's nice value (0 by default, 19 the lowest priority).
int ThisThreadsNice();

// Raises to `nice` (capped at 19) the nice value of each of this process's threads whose name
// (/proc/self/task/TID/comm) starts with `name_prefix` and runs at a lower one: for threads a
// library starts at its creator's priority, such as Mesa's llvmpipe rasteriser threads. Best
// effort; returns how many threads it changed.
int LowerThreadsNamed(const std::string& name_prefix, int nice);

}  // namespace sightmap
