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

// Whether the photo's bytes run to their end marker: for a JPEG, an end-of-image marker (FF D9)
// after its last start-of-scan (an EXIF thumbnail's own end marker comes before the image's
// scans); for a PNG, the IEND chunk in its last bytes. A cut upload fails this while decoders
// still return an image (libjpeg fills the missing rows with grey), which would then be matched
// on invented pixels. Never reads past `size`.
bool PhotoIsComplete(const uint8_t* data, size_t size, PhotoFormat format);

}  // namespace sightmap
