// An image's format, size, bit depth and channels read from its first bytes (JPEG frame header,
// PNG IHDR), without decoding it: `sightmap serve` refuses a 100-megapixel upload before
// cv::imdecode would allocate 300 MB for it, and an RGB-D folder checks its depth maps are 16-bit
// single-channel before reading thousands of them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>

namespace sightmap {

enum class ImageFormat { kJpeg, kPng };
const char* ToString(ImageFormat format);  // "jpeg", "png"

struct ImageHeader {
  ImageFormat format = ImageFormat::kJpeg;
  int width = 0;     // [px]
  int height = 0;    // [px]
  int bits = 8;      // per channel: PNG's bit depth (8 for a palette), JPEG's sample precision
  int channels = 0;  // PNG: by colour type (a palette's 3); JPEG: its components
  int64_t pixels() const { return static_cast<int64_t>(width) * height; }
};

// The format and size of a JPEG (the first SOFn frame header after SOI) or PNG (IHDR). nullopt
// when the bytes are neither, are cut before the size, or state a zero size; never throws and
// never reads past `size` (the bytes may be any HTTP body).
std::optional<ImageHeader> ReadImageHeader(const uint8_t* data, size_t size);

// Whether the photo's bytes run to their end marker: for a JPEG, an end-of-image marker (FF D9)
// after its last start-of-scan (an EXIF thumbnail's own end marker comes before the image's
// scans); for a PNG, the IEND chunk in its last bytes. A cut upload fails this while decoders
// still return an image (libjpeg fills the missing rows with grey), which would then be matched
// on invented pixels. Never reads past `size`.
bool ImageIsComplete(const uint8_t* data, size_t size, ImageFormat format);

}  // namespace sightmap
