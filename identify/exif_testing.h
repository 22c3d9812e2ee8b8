// Test photos with chosen EXIF entries: real JPEGs (cv::imencode) with an APP1 segment written by
// libexif, for the tests of the EXIF reader, the photo decoder and the servers that take photos.
#pragma once

#include <libexif/exif-data.h>

#include <cstdint>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

namespace sightmap::testing {

// The EXIF entries a test photo carries; absent ones are not written.
struct ExifFields {
  std::optional<int> focal_35mm;             // SHORT [mm]
  std::optional<double> focal_mm;            // RATIONAL
  std::optional<double> plane_x_resolution;  // RATIONAL, pixels per unit
  std::optional<double> plane_y_resolution;
  std::optional<double> plane_unit;  // 2 inch, 3 cm, 4 mm; written as plane_unit_format
  ExifFormat plane_unit_format = EXIF_FORMAT_SHORT;
  std::optional<int> pixel_x;  // LONG
  std::optional<int> pixel_y;
  std::optional<int> orientation;  // SHORT in IFD0: 1-8 as the EXIF standard numbers them
  ExifByteOrder order = EXIF_BYTE_ORDER_INTEL;
};

// `image` (BGR) encoded as a JPEG with `fields` spliced in after its SOI. Throws Error when
// encoding fails.
std::vector<uint8_t> JpegWithExif(const cv::Mat& image, const ExifFields& fields);
// The same with a width x height image of random pixels.
std::vector<uint8_t> JpegWithExif(int width, int height, const ExifFields& fields);

}  // namespace sightmap::testing
