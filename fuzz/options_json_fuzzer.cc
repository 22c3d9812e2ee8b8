// libFuzzer harness: config files (`--config FILE` of map, locate and serve), read into the
// options as the commands read them, then checked. A sightmap::Error (InvalidArgument) is the
// right answer to a bad file; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "cli/locate_server.h"
#include "core/check.h"
#include "core/options_json.h"
#include "mapping/mapping_session.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::string error;
  try {
    sightmap::mapping::MappingOptions mapping;
    sightmap::options_json::ParseInto(text, "fuzz.json", mapping);
    mapping.Check(&error);
  } catch (const sightmap::Error&) {
  }
  try {
    sightmap::cli::LocateServerOptions serve;
    sightmap::options_json::ParseInto(text, "fuzz.json", serve);
    serve.Check(&error);
  } catch (const sightmap::Error&) {
  }
  return 0;
}
