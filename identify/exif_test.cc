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
#include "identify/exif_testing.h"
#include "tests/test_data.h"

namespace sightmap::identify {
namespace {

using testing::ExifFields;
using testing::JpegWithExif;

const double kFilmDiagonalMm = std::hypot(36.0, 24.0);

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

// Found by photo_fuzzer: a resolution unit stored as a LONG of billions was cast to int
// (undefined behaviour). An unknown unit gives no derived focal length.
TEST(Exif, AnAbsurdResolutionUnitIsUnknownNotUndefined) {
  ExifFields fields;
  fields.focal_mm = 4.25;
  fields.plane_x_resolution = 4000.0;
  fields.plane_unit = 2718960000.0;
  fields.plane_unit_format = EXIF_FORMAT_LONG;
  EXPECT_FALSE(ExifFocalLength35mm(JpegWithExif(64, 48, fields)).has_value());
  fields.plane_unit = 3.0;  // cm: the same file with a sane unit gives a focal length
  EXPECT_TRUE(ExifFocalLength35mm(JpegWithExif(64, 48, fields)).has_value());
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
}  // namespace sightmap::identify
