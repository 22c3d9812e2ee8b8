// The process's peak memory, as the summaries and benchmarks report it.
#pragma once

namespace sightmap {

// The peak resident set size of this process so far [MiB] (getrusage's ru_maxrss).
double PeakRssMiB();

}  // namespace sightmap
