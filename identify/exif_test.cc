#include "identify/exif.h"

#include <libexif/exif-data.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "core/check.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

const double kFilmDiagonalMm = std::hypot(36.0, 24.0);

// The EXIF entries a test photo carries; absent ones are not written.
struct ExifFields {
  std::optional<int> focal_35mm;             // SHORT [mm]
  std::optional<double> focal_mm;            // RATIONAL
  std::optional<double> plane_x_resolution;  // RATIONAL, pixels per unit
  std::optional<double> plane_y_resolution;
  std::optional<int> plane_unit;  // SHORT: 2 inch, 3 cm, 4 mm
  std::optional<int> pixel_x;     // LONG
  std::optional<int> pixel_y;
  ExifByteOrder order = EXIF_BYTE_ORDER_INTEL;
};

void AddEntry(ExifData* exif, ExifTag tag, ExifFormat format, const ExifFields& fields,
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
    exif_set_short(entry->data, fields.order, static_cast<ExifShort>(value));
  } else if (format == EXIF_FORMAT_LONG) {
    exif_set_long(entry->data, fields.order, static_cast<ExifLong>(value));
  } else {
    const ExifRational rational{static_cast<ExifLong>(std::lround(value * 1000.0)), 1000};
    exif_set_rational(entry->data, fields.order, rational);
  }
  exif_content_add_entry(exif->ifd[EXIF_IFD_EXIF], entry);
  exif_entry_unref(entry);
}

// A real JPEG (cv::imencode) with an APP1 EXIF segment (libexif) spliced in after its SOI.
std::vector<uint8_t> JpegWithExif(int width, int height, const ExifFields& fields) {
  cv::Mat image(height, width, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> jpeg;
  EXPECT_TRUE(cv::imencode(".jpg", image, jpeg));

  ExifData* exif = exif_data_new();
  exif_data_unset_option(exif, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  exif_data_set_byte_order(exif, fields.order);
  if (fields.focal_35mm) {
    AddEntry(exif, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, EXIF_FORMAT_SHORT, fields,
             *fields.focal_35mm);
  }
  if (fields.focal_mm) {
    AddEntry(exif, EXIF_TAG_FOCAL_LENGTH, EXIF_FORMAT_RATIONAL, fields, *fields.focal_mm);
  }
  if (fields.plane_x_resolution) {
    AddEntry(exif, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION, EXIF_FORMAT_RATIONAL, fields,
             *fields.plane_x_resolution);
  }
  if (fields.plane_y_resolution) {
    AddEntry(exif, EXIF_TAG_FOCAL_PLANE_Y_RESOLUTION, EXIF_FORMAT_RATIONAL, fields,
             *fields.plane_y_resolution);
  }
  if (fields.plane_unit) {
    AddEntry(exif, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT, EXIF_FORMAT_SHORT, fields,
             *fields.plane_unit);
  }
  if (fields.pixel_x) {
    AddEntry(exif, EXIF_TAG_PIXEL_X_DIMENSION, EXIF_FORMAT_LONG, fields, *fields.pixel_x);
  }
  if (fields.pixel_y) {
    AddEntry(exif, EXIF_TAG_PIXEL_Y_DIMENSION, EXIF_FORMAT_LONG, fields, *fields.pixel_y);
  }
  unsigned char* block = nullptr;
  unsigned int block_size = 0;
  exif_data_save_data(exif, &block, &block_size);  // "Exif\0\0" + TIFF header + IFDs
  exif_data_unref(exif);
  EXPECT_NE(block, nullptr);
  EXPECT_GT(block_size, 6u);
  EXPECT_LT(block_size, 65000u);

  const size_t segment_length = block_size + 2;  // the length field counts itself
  std::vector<uint8_t> app1 = {0xFF, 0xE1, static_cast<uint8_t>(segment_length >> 8),
                               static_cast<uint8_t>(segment_length & 0xFF)};
  app1.insert(app1.end(), block, block + block_size);
  std::free(block);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  return jpeg;
}

TEST(Exif, ReadsFocalLengthIn35mmFilm) {
  ExifFields fields;
  fields.focal_35mm = 28;
  fields.focal_mm = 4.25;  // ignored: the recorded equivalent wins
  const std::vector<uint8_t> jpeg = JpegWithExif(64, 48, fields);
  EXPECT_EQ(cv::imdecode(jpeg, cv::IMREAD_COLOR).cols, 64);  // still a valid JPEG
  const std::optional<double> focal = ExifFocalLength35mm(jpeg);
  ASSERT_TRUE(focal);
  EXPECT_DOUBLE_EQ(*focal, 28.0);
  fields.order = EXIF_BYTE_ORDER_MOTOROLA;
  EXPECT_EQ(ExifFocalLength35mm(JpegWithExif(64, 48, fields)), 28.0);
}

TEST(Exif, DerivesTheEquivalentFromTheSensorSizeAndTheJpegSize) {
  // A 6.4 x 4.8 mm sensor (8 mm diagonal) imaged at 640x480: 100 px per mm.
  ExifFields fields;
  fields.focal_mm = 4.25;
  fields.plane_x_resolution = 100.0;
  fields.plane_unit = 4;  // mm
  const double expected = 4.25 * kFilmDiagonalMm / 8.0;
  std::optional<double> focal = ExifFocalLength35mm(JpegWithExif(640, 480, fields));
  ASSERT_TRUE(focal);
  EXPECT_NEAR(*focal, expected, 1e-9);
  // A recorded 0 means "unknown" and falls through to the same derivation.
  fields.focal_35mm = 0;
  EXPECT_NEAR(ExifFocalLength35mm(JpegWithExif(640, 480, fields)).value_or(0.0), expected, 1e-9);
  // The same sensor in centimetres.
  fields.plane_x_resolution = 1000.0;
  fields.plane_unit = 3;
  EXPECT_NEAR(ExifFocalLength35mm(JpegWithExif(640, 480, fields)).value_or(0.0), expected, 1e-9);
}

TEST(Exif, DerivationPrefersPixelDimensionsAndDefaultsToInches) {
  // Recorded at 4000x3000 on a 6.4 x 4.8 mm sensor, written out (downscaled) at 400x300: the
  // focal-plane resolution refers to the recorded size. No unit: inches.
  ExifFields fields;
  fields.focal_mm = 4.25;
  fields.plane_x_resolution = 4000.0 / 6.4 * 25.4;
  fields.plane_y_resolution = 3000.0 / 4.8 * 25.4;
  fields.pixel_x = 4000;
  fields.pixel_y = 3000;
  const std::optional<double> focal = ExifFocalLength35mm(JpegWithExif(400, 300, fields));
  ASSERT_TRUE(focal);
  EXPECT_NEAR(*focal, 4.25 * kFilmDiagonalMm / 8.0, 1e-3);
}

TEST(Exif, NothingToReadGivesNullopt) {
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(10, 200, 30));
  std::vector<uint8_t> plain;
  ASSERT_TRUE(cv::imencode(".jpg", image, plain));
  EXPECT_FALSE(ExifFocalLength35mm(plain));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  EXPECT_FALSE(ExifFocalLength35mm(png));
  EXPECT_FALSE(ExifFocalLength35mm(std::vector<uint8_t>()));
  EXPECT_FALSE(ExifFocalLength35mm(nullptr, 100));
  // FocalLength alone cannot be converted without the sensor's size.
  ExifFields focal_only;
  focal_only.focal_mm = 4.25;
  EXPECT_FALSE(ExifFocalLength35mm(JpegWithExif(64, 48, focal_only)));
  // An unknown focal-plane unit.
  ExifFields odd_unit = focal_only;
  odd_unit.plane_x_resolution = 100.0;
  odd_unit.plane_unit = 9;
  EXPECT_FALSE(ExifFocalLength35mm(JpegWithExif(64, 48, odd_unit)));
}

TEST(Exif, GarbageAndTruncatedBytesNeverCrash) {
  std::mt19937 random(5);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> garbage(static_cast<size_t>(trial * 37 % 3000));
    for (uint8_t& b : garbage) b = static_cast<uint8_t>(byte(random));
    if (trial % 2 == 0 && garbage.size() >= 4) {  // a JPEG and EXIF start, then noise
      garbage[0] = 0xFF;
      garbage[1] = 0xD8;
      garbage[2] = 0xFF;
      garbage[3] = 0xE1;
    }
    const std::optional<double> focal = ExifFocalLength35mm(garbage);
    if (focal) {
      EXPECT_TRUE(std::isfinite(*focal));
    }
  }
  ExifFields fields;
  fields.focal_35mm = 26;
  const std::vector<uint8_t> jpeg = JpegWithExif(64, 48, fields);
  for (size_t size = 0; size < jpeg.size(); size += 7) {
    const std::optional<double> focal = ExifFocalLength35mm(jpeg.data(), size);
    if (focal) {
      EXPECT_DOUBLE_EQ(*focal, 26.0);
    }
  }
  // Noise in the middle of the EXIF block.
  std::vector<uint8_t> damaged = jpeg;
  for (size_t i = 20; i < 60 && i < damaged.size(); ++i) damaged[i] ^= 0x5A;
  const std::optional<double> focal = ExifFocalLength35mm(damaged);
  if (focal) {
    EXPECT_TRUE(std::isfinite(*focal));
  }
}

TEST(Exif, ReadsAFile) {
  const std::string dir = testing::MakeTempDir("exif_file");
  ExifFields fields;
  fields.focal_35mm = 24;
  const std::vector<uint8_t> jpeg = JpegWithExif(64, 48, fields);
  std::ofstream(dir + "/photo.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(jpeg.data()), static_cast<std::streamsize>(jpeg.size()));
  EXPECT_EQ(ExifFocalLength35mmOfFile(dir + "/photo.jpg"), 24.0);
  EXPECT_FALSE(ExifFocalLength35mmOfFile(dir + "/missing.jpg"));
}

TEST(IntrinsicsFromFocal35mm, DiagonalEquivalence) {
  // A 3600x2400 image is the film frame at 100 px per mm: 50 mm is 5000 px.
  const Intrinsics k = IntrinsicsFromFocal35mm(3600, 2400, 50.0);
  EXPECT_EQ(k.width, 3600);
  EXPECT_EQ(k.height, 2400);
  EXPECT_NEAR(k.fx, 5000.0, 1e-9);
  EXPECT_NEAR(k.fy, 5000.0, 1e-9);
  EXPECT_DOUBLE_EQ(k.cx, 1799.5);
  EXPECT_DOUBLE_EQ(k.cy, 1199.5);
  // A 4:3 phone photo at 26 mm: the diagonal field of view matches the film frame's.
  const Intrinsics phone = IntrinsicsFromFocal35mm(1280, 960, 26.0);
  EXPECT_NEAR(2.0 * std::atan(std::hypot(1280, 960) / 2.0 / phone.fx),
              2.0 * std::atan(kFilmDiagonalMm / 2.0 / 26.0), 1e-12);
  std::string error;
  EXPECT_TRUE(phone.Check(&error)) << error;
  EXPECT_THROW(IntrinsicsFromFocal35mm(0, 960, 26.0), InvalidArgument);
  EXPECT_THROW(IntrinsicsFromFocal35mm(1280, 960, 0.0), InvalidArgument);
  EXPECT_THROW(IntrinsicsFromFocal35mm(1280, 960, NAN), InvalidArgument);
}

}  // namespace
}  // namespace sightmap
