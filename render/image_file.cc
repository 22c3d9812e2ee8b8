#include "render/image_file.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "core/check.h"

namespace sightmap {

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
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    SIGHTMAP_CHECK(out.good(), "cannot create " << temporary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out.good()) {
      std::remove(temporary.c_str());
      SIGHTMAP_THROW(Error, "cannot write " << temporary << " (disk full?)");
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::remove(temporary.c_str());
    SIGHTMAP_THROW(Error,
                   "cannot rename " << temporary << " to " << path << ": " << error.message());
  }
}

}  // namespace sightmap
