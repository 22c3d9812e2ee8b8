#include "fuzz/fuzz_inputs.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

namespace sightmap::fuzz {

std::string JoinParts(const std::vector<std::string>& parts) {
  std::string joined;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) joined.push_back('\0');
    joined += parts[i];
  }
  return joined;
}

std::vector<std::string> SplitParts(const uint8_t* data, size_t size, size_t count) {
  std::vector<std::string> parts(count);
  size_t part = 0;
  for (size_t i = 0; i < size; ++i) {
    const char c = static_cast<char>(data[i]);
    if (c == '\0' && part + 1 < count) {
      ++part;
    } else {
      parts[part].push_back(c);
    }
  }
  return parts;
}

void WriteParts(const uint8_t* data, size_t size, const std::string& dir,
                const std::vector<std::string>& names) {
  const std::vector<std::string> parts = SplitParts(data, size, names.size());
  for (size_t i = 0; i < names.size(); ++i) WriteFile(dir + "/" + names[i], parts[i]);
}

void WriteTinyFrame(const std::string& color_path, const std::string& depth_path) {
  if (!cv::imwrite(color_path, cv::Mat(12, 16, CV_8UC3, cv::Scalar(9, 99, 199))) ||
      !cv::imwrite(depth_path, cv::Mat(12, 16, CV_16UC1, cv::Scalar(5000)))) {
    std::fprintf(stderr, "fuzz harness: cannot write %s\n", color_path.c_str());
    std::abort();
  }
}

namespace {

// The process's scratch folder, removed when the process exits normally (libFuzzer's -runs and
// -max_total_time end with exit()); after a crash it stays, holding the input that crashed.
class ScratchFolder {
 public:
  ScratchFolder()
      : path_((std::filesystem::temp_directory_path() /
               ("sightmap-fuzz-" + std::to_string(::getpid())))
                  .string()) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchFolder() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;

  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace

const std::string& ScratchDir() {
  static const ScratchFolder folder;
  return folder.path();
}

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.good()) {
    std::fprintf(stderr, "fuzz harness: cannot write %s\n", path.c_str());
    std::abort();
  }
}

}  // namespace sightmap::fuzz
