// libFuzzer harness: calibration files (`--calib FILE`), read as `map`, `probe` and `locate` read
// them. A sightmap::Error is the right answer to a bad file; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "capture/calibration.h"
#include "core/check.h"
#include "fuzz/fuzz_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = sightmap::fuzz::ScratchDir() + "/calibration.json";
  sightmap::fuzz::WriteFile(path, std::string(reinterpret_cast<const char*>(data), size));
  try {
    const sightmap::capture::RgbdCalibration calibration =
        sightmap::capture::ReadCalibrationFile(path);
    if (calibration.color) calibration.color->Scaled(320, 240);
  } catch (const sightmap::Error&) {
  }
  return 0;
}
