// libFuzzer harness: a TUM RGB-D folder's lists (`tum:DIR`). The input is rgb.txt, depth.txt and
// groundtruth.txt joined by NUL bytes (fuzz_inputs.h); the images they may name (rgb/0.png,
// depth/0.png, rgb/1.png, depth/1.png) exist. The folder is opened and played to its end. A
// sightmap::Error is the right answer to a bad folder; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/folder_source.h"
#include "core/check.h"
#include "fuzz/fuzz_inputs.h"

namespace {

const std::string& Folder() {
  static const std::string dir = [] {
    const std::string root = sightmap::fuzz::ScratchDir() + "/tum";
    for (const char* sub : {"rgb", "depth"}) std::filesystem::create_directories(root + "/" + sub);
    for (const char* name : {"0", "1"}) {
      sightmap::fuzz::WriteTinyFrame(root + "/rgb/" + name + ".png",
                                     root + "/depth/" + name + ".png");
    }
    return root;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& dir = Folder();
  sightmap::fuzz::WriteParts(data, size, dir, {"rgb.txt", "depth.txt", "groundtruth.txt"});
  try {
    std::unique_ptr<sightmap::capture::RgbdSource> source =
        sightmap::capture::OpenTumFolder(dir, sightmap::capture::SourceOptions());
    for (int frames = 0; frames < 4 && source->Next(); ++frames) {
    }
  } catch (const sightmap::Error&) {
  }
  return 0;
}
