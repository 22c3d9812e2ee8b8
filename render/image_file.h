// Writing images so that a reader never sees half a file.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace sightmap::render {

// Encodes `image` by the extension of `path` (.png, .jpg), writes PATH.tmp beside it and renames
// it over `path` (atomic on POSIX file systems). Throws sightmap::Error on failure and removes the
// temporary file.
void WriteImageAtomically(const std::string& path, const cv::Mat& image);

}  // namespace sightmap::render
