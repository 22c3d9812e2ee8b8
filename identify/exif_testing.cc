#include "identify/exif_testing.h"

#include <cmath>
#include <cstdlib>

#include <opencv2/imgcodecs.hpp>

#include "core/check.h"

namespace sightmap::testing {
namespace {

void AddEntry(ExifData* exif, ExifIfd ifd, ExifTag tag, ExifFormat format, ExifByteOrder order,
              double value) {
  ExifEntry* entry = exif_entry_new();
  entry->tag = tag;
  entry->format = format;
  entry->components = 1;
  entry->size = exif_format_get_size(format);
  ExifMem* mem = exif_mem_new_default();
  entry->data = static_cast<unsigned char*>(exif_mem_alloc(mem, entry->size));
  exif_mem_unref(mem);
  if (format == EXIF_FORMAT_SHORT) {
    exif_set_short(entry->data, order, static_cast<ExifShort>(value));
  } else if (format == EXIF_FORMAT_LONG) {
    exif_set_long(entry->data, order, static_cast<ExifLong>(value));
  } else {
    const ExifRational rational{static_cast<ExifLong>(std::lround(value * 1000.0)), 1000};
    exif_set_rational(entry->data, order, rational);
  }
  exif_content_add_entry(exif->ifd[ifd], entry);
  exif_entry_unref(entry);
}

}  // namespace

std::vector<uint8_t> JpegWithExif(const cv::Mat& image, const ExifFields& fields) {
  std::vector<uint8_t> jpeg;
  SIGHTMAP_CHECK(cv::imencode(".jpg", image, jpeg), "cannot encode the test JPEG");

  ExifData* exif = exif_data_new();
  exif_data_unset_option(exif, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  exif_data_set_byte_order(exif, fields.order);
  const auto add = [&](ExifIfd ifd, ExifTag tag, ExifFormat format, const auto& value) {
    if (value) AddEntry(exif, ifd, tag, format, fields.order, static_cast<double>(*value));
  };
  add(EXIF_IFD_EXIF, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, EXIF_FORMAT_SHORT, fields.focal_35mm);
  add(EXIF_IFD_EXIF, EXIF_TAG_FOCAL_LENGTH, EXIF_FORMAT_RATIONAL, fields.focal_mm);
  add(EXIF_IFD_EXIF, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION, EXIF_FORMAT_RATIONAL,
      fields.plane_x_resolution);
  add(EXIF_IFD_EXIF, EXIF_TAG_FOCAL_PLANE_Y_RESOLUTION, EXIF_FORMAT_RATIONAL,
      fields.plane_y_resolution);
  add(EXIF_IFD_EXIF, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT, fields.plane_unit_format,
      fields.plane_unit);
  add(EXIF_IFD_EXIF, EXIF_TAG_PIXEL_X_DIMENSION, EXIF_FORMAT_LONG, fields.pixel_x);
  add(EXIF_IFD_EXIF, EXIF_TAG_PIXEL_Y_DIMENSION, EXIF_FORMAT_LONG, fields.pixel_y);
  add(EXIF_IFD_0, EXIF_TAG_ORIENTATION, EXIF_FORMAT_SHORT, fields.orientation);

  unsigned char* block = nullptr;
  unsigned int block_size = 0;
  exif_data_save_data(exif, &block, &block_size);  // "Exif\0\0" + TIFF header + IFDs
  exif_data_unref(exif);
  SIGHTMAP_CHECK(block != nullptr && block_size > 6 && block_size < 65000,
                 "libexif wrote a " << block_size << "-byte EXIF block");

  const size_t segment_length = block_size + 2;  // the length field counts itself
  std::vector<uint8_t> app1 = {0xFF, 0xE1, static_cast<uint8_t>(segment_length >> 8),
                               static_cast<uint8_t>(segment_length & 0xFF)};
  app1.insert(app1.end(), block, block + block_size);
  std::free(block);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  return jpeg;
}

std::vector<uint8_t> JpegWithExif(int width, int height, const ExifFields& fields) {
  cv::Mat image(height, width, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  return JpegWithExif(image, fields);
}

}  // namespace sightmap::testing
