// A phone photo's focal length from its EXIF, so `sightmap locate` and `serve` can build
// intrinsics for a photo that came with nothing else (the paper's phones all wrote EXIF).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"

namespace sightmap::identify {

// What sightmap reads from a JPEG's EXIF, in one pass over its bytes: never throws on bad input
// (the bytes may be any HTTP body), and gives the defaults when they are not a JPEG with EXIF.
struct ExifFacts {
  // The Orientation tag (0x0112, IFD0): 1-8, or 1 when it is absent or out of range.
  int orientation = 1;
  // As ExifFocalLength35mm below [mm].
  std::optional<double> focal_35mm;
};
ExifFacts ReadExifFacts(const uint8_t* data, size_t size);

// The EXIF Orientation of a JPEG (ReadExifFacts(...).orientation).
int ExifOrientation(const uint8_t* data, size_t size);

// The 35 mm-equivalent focal length [mm] recorded in a JPEG's EXIF: FocalLengthIn35mmFilm (0xA405)
// when present and non-zero; else derived from FocalLength (0x920A) and the sensor's size,
// FocalPlaneX/YResolution (0xA20E/0xA20F) in FocalPlaneResolutionUnit (0xA210, inch by default)
// over the image's size (PixelX/YDimension, else the JPEG's own frame header), on the diagonal as
// IntrinsicsFromFocal35mm. nullopt when the bytes are not a JPEG, carry no EXIF, or neither way
// gives a plausible value; never throws on bad input (the bytes may be any HTTP body).
std::optional<double> ExifFocalLength35mm(const uint8_t* data, size_t size);
std::optional<double> ExifFocalLength35mm(const std::vector<uint8_t>& jpeg);
// The same for a file; nullopt also when it cannot be read.
std::optional<double> ExifFocalLength35mmOfFile(const std::string& path);

// Pinhole intrinsics of a width x height [px] image taken at a 35 mm-equivalent focal length
// [mm]. The equivalence is defined on the diagonal (a 36 x 24 mm frame, 43.27 mm):
// f_px = focal_35mm * hypot(width, height) / hypot(36, 24); square pixels; principal point at the
// image centre ((width - 1) / 2, (height - 1) / 2), pixel centres at integer coordinates.
// Throws InvalidArgument on a non-positive size or focal length.
Intrinsics IntrinsicsFromFocal35mm(int width, int height, double focal_35mm);

}  // namespace sightmap::identify
