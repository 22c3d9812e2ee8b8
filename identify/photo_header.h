// A photo's format and size read from its first bytes (JPEG frame header, PNG IHDR), without
// decoding it: `sightmap serve` refuses a 100-megapixel upload before cv::imdecode would allocate
// 300 MB for it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>

namespace sightmap {

enum class PhotoFormat { kJpeg, kPng };
const char* ToString(PhotoFormat format);  // "jpeg", "png"

struct PhotoHeader {
  PhotoFormat format = PhotoFormat::kJpeg;
  int width = 0;   // [px]
  int height = 0;  // [px]
  int64_t pixels() const { return static_cast<int64_t>(width) * height; }
};

// The format and size of a JPEG (the first SOFn frame header after SOI) or PNG (IHDR). nullopt
// when the bytes are neither, are cut before the size, or state a zero size; never throws and
// never reads past `size` (the bytes may be any HTTP body).
std::optional<PhotoHeader> ReadPhotoHeader(const uint8_t* data, size_t size);

}  // namespace sightmap
