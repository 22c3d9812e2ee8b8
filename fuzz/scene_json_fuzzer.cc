// libFuzzer harness: the simulator's scene JSON (`sim:FILE.json`, `sim generate --scene FILE`),
// parsed and given a second session's changes. A sightmap::Error is the right answer to a bad
// file; anything else (another exception, a sanitizer report, a crash) is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/check.h"
#include "sim/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const sightmap::sim::Scene scene = sightmap::sim::ParseScene(
        std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
    sightmap::sim::ApplySession(scene, 2, 7);
  } catch (const sightmap::Error&) {
  }
  return 0;
}
