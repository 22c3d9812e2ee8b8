// libFuzzer harness: CloudCompare point lists (`label import FILE`, the paper's label format),
// read and imported into an in-memory model as a label named after the file. A sightmap::Error
// is the right answer to a bad file; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/check.h"
#include "fuzz/fuzz_inputs.h"
#include "identify/labels.h"
#include "store/label_files.h"
#include "store/model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = sightmap::fuzz::ScratchDir() + "/kettle.txt";
  sightmap::fuzz::WriteFile(path, std::string(reinterpret_cast<const char*>(data), size));
  try {
    sightmap::store::ReadPointList(path);
    sightmap::store::Model model = sightmap::store::Model::Open(":memory:");
    sightmap::identify::ImportPointListLabels(model, {path}, "kettle");
  } catch (const sightmap::Error&) {
  }
  return 0;
}
