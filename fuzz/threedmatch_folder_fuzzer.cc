// libFuzzer harness: a 3DMatch sequence's text files (`3dmatch:DIR`). The input is
// camera-intrinsics.txt, frame-000000.pose.txt and frame-000001.pose.txt joined by NUL bytes
// (fuzz_inputs.h); both frames' images exist. The folder is opened and played to its end. A
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
    const std::string root = sightmap::fuzz::ScratchDir() + "/3dmatch";
    std::filesystem::create_directories(root);
    for (const std::string frame : {"frame-000000", "frame-000001"}) {
      sightmap::fuzz::WriteTinyFrame(root + "/" + frame + ".color.png",
                                     root + "/" + frame + ".depth.png");
    }
    return root;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& dir = Folder();
  sightmap::fuzz::WriteParts(
      data, size, dir, {"camera-intrinsics.txt", "frame-000000.pose.txt", "frame-000001.pose.txt"});
  try {
    std::unique_ptr<sightmap::capture::RgbdSource> source =
        sightmap::capture::OpenThreeDMatchFolder(dir, sightmap::capture::SourceOptions());
    for (int frames = 0; frames < 4 && source->Next(); ++frames) {
    }
  } catch (const sightmap::Error&) {
  }
  return 0;
}
