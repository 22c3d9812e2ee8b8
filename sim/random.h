// Reproducible random numbers for the simulator. std::mt19937_64's output is fixed by the C++
// standard; the distributions below are written out here (std::uniform_real_distribution and
// std::normal_distribution are implementation-defined), so a seed gives the same walk, photos and
// noise with any standard library.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace sightmap::sim {

// A well-mixed 64-bit seed from a base seed and a stream number (SplitMix64 finaliser), so each
// frame, photo or session draws from its own independent stream.
inline uint64_t MixSeed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform in [lo, hi) from the top 53 bits.
inline double UniformReal(std::mt19937_64& rng, double lo, double hi) {
  const double unit = static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
  return lo + (hi - lo) * unit;
}

// Standard normal by Box-Muller.
inline double StandardNormal(std::mt19937_64& rng) {
  constexpr double kTwoPi = 6.283185307179586;
  double u1 = UniformReal(rng, 0.0, 1.0);
  if (u1 < 1e-300) u1 = 1e-300;
  const double u2 = UniformReal(rng, 0.0, 1.0);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

}  // namespace sightmap::sim
