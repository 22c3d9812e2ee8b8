#include "core/peak_memory.h"

#include <cstring>
#include <memory>

#include <gtest/gtest.h>

namespace sightmap {
namespace {

TEST(PeakMemory, GrowsWithMemoryTouched) {
  const double before = PeakRssMiB();
  EXPECT_GT(before, 1.0);  // a running test binary holds more than a MiB
  // More than the peak so far, so that the new peak exceeds it whatever is resident now.
  const size_t bytes = (static_cast<size_t>(before) + 256) << 20;
  const std::unique_ptr<char[]> block(new char[bytes]);
  std::memset(block.get(), 1, bytes);  // resident only once written
  EXPECT_GT(PeakRssMiB(), before + 200.0);
  EXPECT_EQ(block[bytes - 1], 1);
}

}  // namespace
}  // namespace sightmap
