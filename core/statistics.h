// Summary statistics of measured values (timings, errors) shared by the summaries and benchmarks.
#pragma once

#include <vector>

namespace sightmap {

// The linear-interpolation percentile (q in [0, 1]) of `values`; 0 when empty.
double Percentile(std::vector<double> values, double q);

}  // namespace sightmap
