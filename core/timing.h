// Wall time between two points of the program, as every stage's timings and progress report it.
#pragma once

#include <chrono>

namespace sightmap {

// Seconds from `start` to now on the steady clock.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace sightmap
