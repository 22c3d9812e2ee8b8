// libFuzzer harness: the PLY reader (`ReadPly`, which tools and tests read `map --ply` output
// with). A sightmap::Error is the right answer to a bad file; anything else is a
// finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/check.h"
#include "fuzz/fuzz_inputs.h"
#include "store/point_cloud.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = sightmap::fuzz::ScratchDir() + "/cloud.ply";
  sightmap::fuzz::WriteFile(path, std::string(reinterpret_cast<const char*>(data), size));
  try {
    sightmap::store::ReadPly(path);
  } catch (const sightmap::Error&) {
  }
  return 0;
}
