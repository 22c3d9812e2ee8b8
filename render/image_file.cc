#include "render/image_file.h"

#include <filesystem>
#include <string_view>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/check.h"

namespace sightmap::render {

void WriteImageAtomically(const std::string& path, const cv::Mat& image) {
  SIGHTMAP_CHECK(!image.empty(), "refusing to write an empty image to " << path);
  const std::string extension = std::filesystem::path(path).extension().string();
  std::vector<uchar> bytes;
  bool encoded = false;
  try {
    encoded = cv::imencode(extension.empty() ? ".png" : extension, image, bytes);
  } catch (const cv::Exception& e) {
    SIGHTMAP_THROW(Error, "cannot encode an image for " << path << ": " << e.what());
  }
  SIGHTMAP_CHECK(encoded, "cannot encode an image for " << path);
  WriteFileAtomically(path,
                      std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace sightmap::render
