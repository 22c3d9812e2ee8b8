#include "identify/photo.h"

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "identify/exif.h"
#include "identify/exif_testing.h"

namespace sightmap::identify {
namespace {

using testing::ExifFields;
using testing::JpegWithExif;

// A landscape image whose quadrants differ, so any turn or mirror shows.
cv::Mat Quadrants(int width, int height) {
  cv::Mat image(height, width, CV_8UC3, cv::Scalar(0, 0, 0));
  image(cv::Rect(0, 0, width / 2, height / 2)).setTo(cv::Scalar(255, 0, 0));
  image(cv::Rect(width / 2, 0, width - width / 2, height / 2)).setTo(cv::Scalar(0, 255, 0));
  image(cv::Rect(0, height / 2, width / 2, height - height / 2)).setTo(cv::Scalar(0, 0, 255));
  return image;
}

double MeanAbsDifference(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_L1) / static_cast<double>(a.total() * a.channels());
}

// A point's camera-frame coordinates after the camera turns a quarter clockwise about its axis.
Eigen::Vector3d TurnPointClockwise(const Eigen::Vector3d& point, int quarter_turns) {
  Eigen::Vector3d turned = point;
  for (int i = 0; i < quarter_turns; ++i)
    turned = Eigen::Vector3d(-turned.y(), turned.x(), turned.z());
  return turned;
}

TEST(PhotoOrientation, CodesAsTurnsAndMirrors) {
  EXPECT_EQ(PhotoOrientation::FromExif(1).quarter_turns_cw, 0);
  EXPECT_EQ(PhotoOrientation::FromExif(3).quarter_turns_cw, 2);
  EXPECT_EQ(PhotoOrientation::FromExif(6).quarter_turns_cw, 1);
  EXPECT_EQ(PhotoOrientation::FromExif(8).quarter_turns_cw, 3);
  for (int code : {2, 4, 5, 7}) EXPECT_TRUE(PhotoOrientation::FromExif(code).mirrored) << code;
  for (int code : {1, 3, 6, 8}) EXPECT_FALSE(PhotoOrientation::FromExif(code).mirrored) << code;
  for (int code : {0, 9, -1, 65535}) {
    EXPECT_EQ(PhotoOrientation::FromExif(code).exif_code, 1) << code;
    EXPECT_EQ(PhotoOrientation::FromExif(code).quarter_turns_cw, 0) << code;
  }
}

// Every code's turn and mirror reproduce the picture the EXIF standard describes: the stored
// pixels are what the display shows, transformed by the code's inverse.
TEST(PhotoOrientation, TurnThenMirrorShowsTheStandardsPicture) {
  const cv::Mat shown = Quadrants(40, 30);
  // The stored pixels for each code, made by undoing the display transform with OpenCV.
  for (int code = 1; code <= 8; ++code) {
    const PhotoOrientation orientation = PhotoOrientation::FromExif(code);
    cv::Mat stored = shown.clone();
    if (orientation.mirrored) cv::flip(stored, stored, 1);
    stored = TurnClockwise(stored, 4 - orientation.quarter_turns_cw);
    cv::Mat displayed = TurnClockwise(stored, orientation.quarter_turns_cw);
    if (orientation.mirrored) cv::flip(displayed, displayed, 1);
    ASSERT_EQ(displayed.size(), shown.size()) << code;
    EXPECT_EQ(MeanAbsDifference(displayed, shown), 0.0) << code;
  }
  // Code 6 as the standard words it: "the 0th row is the visual right-hand side of the image,
  // the 0th column the visual top". Stored so, it shows as `shown`.
  cv::Mat stored6(shown.cols, shown.rows, shown.type());
  for (int row = 0; row < stored6.rows; ++row) {
    for (int col = 0; col < stored6.cols; ++col) {
      stored6.at<cv::Vec3b>(row, col) = shown.at<cv::Vec3b>(col, shown.cols - 1 - row);
    }
  }
  EXPECT_EQ(MeanAbsDifference(
                TurnClockwise(stored6, PhotoOrientation::FromExif(6).quarter_turns_cw), shown),
            0.0);
}

TEST(TurnClockwise, IntrinsicsTurnWithTheirPixels) {
  const Intrinsics stored = Intrinsics::FromPinhole(640, 480, 500.0, 520.0, 300.0, 250.0);
  const Eigen::Vector3d point(0.3, -0.2, 2.0);
  const Eigen::Vector2d pixel = stored.Project(point);
  cv::Mat image(stored.height, stored.width, CV_8UC1, cv::Scalar(0));
  image.at<uint8_t>(static_cast<int>(std::lround(pixel.y())),
                    static_cast<int>(std::lround(pixel.x()))) = 255;
  for (int turns = 0; turns < 4; ++turns) {
    const Intrinsics turned = TurnClockwise(stored, turns);
    const cv::Mat turned_image = TurnClockwise(image, turns);
    EXPECT_EQ(turned.width, turned_image.cols);
    EXPECT_EQ(turned.height, turned_image.rows);
    cv::Point marker;
    cv::minMaxLoc(turned_image, nullptr, nullptr, nullptr, &marker);
    const Eigen::Vector2d expected = turned.Project(TurnPointClockwise(point, turns));
    EXPECT_NEAR(expected.x(), marker.x, 0.5) << turns;
    EXPECT_NEAR(expected.y(), marker.y, 0.5) << turns;
  }
  const Intrinsics round_trip = TurnClockwise(TurnClockwise(stored, 1), 3);
  EXPECT_DOUBLE_EQ(round_trip.cx, stored.cx);
  EXPECT_DOUBLE_EQ(round_trip.cy, stored.cy);
  EXPECT_DOUBLE_EQ(round_trip.fx, stored.fx);
}

TEST(DecodePhoto, AnOrientationSixJpegIsTurnedUpright) {
  const cv::Mat shown = Quadrants(300, 400);  // portrait, as the phone's screen showed it
  cv::Mat stored;
  cv::rotate(shown, stored, cv::ROTATE_90_COUNTERCLOCKWISE);  // 400x300, as the sensor wrote it
  ExifFields fields;
  fields.orientation = 6;
  fields.focal_35mm = 26;
  const std::vector<uint8_t> jpeg = JpegWithExif(stored, fields);
  EXPECT_EQ(ExifOrientation(jpeg.data(), jpeg.size()), 6);

  // Inspection alone knows the upright size: a server judges the query's intrinsics with it.
  const Photo inspected = InspectPhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels);
  EXPECT_TRUE(inspected.upright.empty());
  EXPECT_EQ(inspected.width(), 300);
  EXPECT_EQ(inspected.height(), 400);

  const Photo photo = DecodePhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels);
  EXPECT_EQ(photo.stored.width, 400);
  EXPECT_EQ(photo.stored.height, 300);
  EXPECT_EQ(photo.orientation.exif_code, 6);
  ASSERT_EQ(photo.width(), 300);
  ASSERT_EQ(photo.height(), 400);
  cv::Mat decoded_stored = cv::imdecode(jpeg, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  cv::rotate(decoded_stored, decoded_stored, cv::ROTATE_90_CLOCKWISE);
  EXPECT_EQ(MeanAbsDifference(photo.upright, decoded_stored), 0.0);
  EXPECT_LT(MeanAbsDifference(photo.upright, shown), 10.0);  // JPEG ringing at the edges only

  // EXIF focal length: square pixels on the upright image, centred.
  const ChosenIntrinsics exif = ChooseIntrinsics(photo, IntrinsicsHint());
  ASSERT_TRUE(exif.intrinsics);
  EXPECT_EQ(exif.source, IntrinsicsSource::kExif);
  EXPECT_EQ(exif.intrinsics->width, 300);
  EXPECT_EQ(exif.intrinsics->height, 400);
  EXPECT_DOUBLE_EQ(exif.intrinsics->fx, exif.intrinsics->fy);
  EXPECT_DOUBLE_EQ(exif.intrinsics->cx, 149.5);
  EXPECT_DOUBLE_EQ(exif.intrinsics->cy, 199.5);
  EXPECT_NEAR(exif.intrinsics->fx, 26.0 * 500.0 / std::hypot(36.0, 24.0), 1e-9);

  // A landscape sensor calibration at twice the size: scaled evenly, then turned (fx and fy
  // swap), never stretched to the portrait size.
  IntrinsicsHint calibration;
  calibration.sensor = Intrinsics::FromPinhole(800, 600, 700.0, 710.0, 401.5, 297.5);
  const ChosenIntrinsics calibrated = ChooseIntrinsics(photo, calibration);
  ASSERT_TRUE(calibrated.intrinsics);
  EXPECT_EQ(calibrated.source, IntrinsicsSource::kCalibration);
  EXPECT_EQ(calibrated.intrinsics->width, 300);
  EXPECT_EQ(calibrated.intrinsics->height, 400);
  EXPECT_DOUBLE_EQ(calibrated.intrinsics->fx, 355.0);
  EXPECT_DOUBLE_EQ(calibrated.intrinsics->fy, 350.0);
  EXPECT_DOUBLE_EQ(calibrated.intrinsics->cx, 299.0 - ((297.5 + 0.5) * 0.5 - 0.5));
  EXPECT_DOUBLE_EQ(calibrated.intrinsics->cy, (401.5 + 0.5) * 0.5 - 0.5);

  // Given intrinsics are the upright picture's; a portrait size of the same aspect is scaled.
  IntrinsicsHint given;
  given.upright = Intrinsics::FromPinhole(600, 800, 480.0, 480.0, 299.5, 399.5);
  const ChosenIntrinsics chosen = ChooseIntrinsics(photo, given);
  ASSERT_TRUE(chosen.intrinsics);
  EXPECT_EQ(chosen.source, IntrinsicsSource::kGiven);
  EXPECT_DOUBLE_EQ(chosen.intrinsics->fx, 240.0);
  EXPECT_DOUBLE_EQ(chosen.intrinsics->fy, 240.0);
  // Landscape intrinsics for a portrait picture are another camera: refused, with the sizes.
  given.upright = Intrinsics::FromPinhole(800, 600, 480.0, 480.0, 399.5, 299.5);
  try {
    ChooseIntrinsics(photo, given);
    FAIL() << "landscape intrinsics were stretched onto a portrait photo";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("800x600"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("300x400"), std::string::npos) << e.what();
  }
}

TEST(DecodePhoto, AMirroredOrientationIsLocatedUnmirroredAndAnsweredInTheShownPicture) {
  const cv::Mat stored = Quadrants(80, 64);
  ExifFields fields;
  fields.orientation = 2;  // shown mirrored left-right
  const std::vector<uint8_t> jpeg = JpegWithExif(stored, fields);
  const Photo photo = DecodePhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels);
  EXPECT_TRUE(photo.orientation.mirrored);
  // Not mirrored: exactly the decoder's stored pixels.
  EXPECT_EQ(MeanAbsDifference(photo.upright,
                              cv::imdecode(jpeg, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION)),
            0.0);
  const Eigen::Vector2d shown = photo.DisplayPixel(Eigen::Vector2d(5.0, 7.0));
  EXPECT_DOUBLE_EQ(shown.x(), 74.0);
  EXPECT_DOUBLE_EQ(shown.y(), 7.0);
}

TEST(DecodePhoto, APngAndAJpegWithoutExifStayAsStored) {
  const cv::Mat image = Quadrants(96, 64);
  for (const std::string extension : {".png", ".jpg"}) {
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(cv::imencode(extension, image, bytes));
    const Photo photo = DecodePhoto(bytes.data(), bytes.size(), kMaxPhotoMegapixels);
    EXPECT_EQ(photo.orientation.exif_code, 1);
    EXPECT_EQ(photo.width(), 96);
    EXPECT_EQ(photo.height(), 64);
    EXPECT_FALSE(photo.exif_focal_35mm);
    EXPECT_EQ(ChooseIntrinsics(photo, IntrinsicsHint()).source, IntrinsicsSource::kEstimated);
    EXPECT_FALSE(ChooseIntrinsics(photo, IntrinsicsHint()).intrinsics);
  }
}

PhotoProblem ProblemOf(const std::vector<uint8_t>& bytes, double max_megapixels) {
  try {
    DecodePhoto(bytes.data(), bytes.size(), max_megapixels);
  } catch (const PhotoRejected& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line";
    return e.problem();
  }
  ADD_FAILURE() << "accepted";
  return PhotoProblem::kCorrupt;
}

TEST(DecodePhoto, RefusesWithTheProblemNamed) {
  const cv::Mat image = Quadrants(200, 100);
  std::vector<uint8_t> png;
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  ASSERT_TRUE(cv::imencode(".jpg", image, jpeg));
  const std::string text = "GIF89a, or any other bytes";
  EXPECT_EQ(ProblemOf(std::vector<uint8_t>(text.begin(), text.end()), 10.0),
            PhotoProblem::kNotAnImage);
  EXPECT_EQ(ProblemOf({}, 10.0), PhotoProblem::kNotAnImage);
  EXPECT_EQ(ProblemOf(jpeg, 0.01), PhotoProblem::kTooLarge);  // 0.02 megapixels
  EXPECT_EQ(ProblemOf(std::vector<uint8_t>(jpeg.begin(), jpeg.begin() + jpeg.size() / 2), 10.0),
            PhotoProblem::kTruncated);
  EXPECT_EQ(ProblemOf(std::vector<uint8_t>(png.begin(), png.end() - 20), 10.0),
            PhotoProblem::kTruncated);
  // Complete in form, garbage inside: the PNG's image data scrambled keeps header and IEND.
  std::vector<uint8_t> scrambled = png;
  for (size_t i = 60; i + 20 < scrambled.size(); ++i) scrambled[i] ^= 0x5A;
  EXPECT_EQ(ProblemOf(scrambled, 10.0), PhotoProblem::kCorrupt);
}

// Too small to hold a feature: refused from the header (OpenCV's feature pyramid threw on a 1-px
// side), whatever the format and whichever side is short; the minimum itself is taken.
TEST(DecodePhoto, RefusesAPhotoTooSmallForFeatures) {
  for (const cv::Size size :
       {cv::Size(1, 1), cv::Size(1, 1000), cv::Size(1000, 1), cv::Size(kMinPhotoSidePx - 1, 480)}) {
    for (const std::string extension : {".png", ".jpg"}) {
      std::vector<uint8_t> bytes;
      ASSERT_TRUE(cv::imencode(extension, cv::Mat(size, CV_8UC3, cv::Scalar(9, 9, 9)), bytes));
      EXPECT_EQ(ProblemOf(bytes, kMaxPhotoMegapixels), PhotoProblem::kTooSmall)
          << size << extension;
    }
  }
  std::vector<uint8_t> smallest;
  ASSERT_TRUE(cv::imencode(".jpg", Quadrants(kMinPhotoSidePx, kMinPhotoSidePx), smallest));
  EXPECT_EQ(DecodePhoto(smallest.data(), smallest.size(), kMaxPhotoMegapixels).width(),
            kMinPhotoSidePx);
}

// A JPEG cut short and closed with an end marker passes the end-marker check; libjpeg decodes it
// with the missing rows grey and only warns. Refused with libjpeg's reason, for a baseline and a
// progressive JPEG alike.
TEST(DecodePhoto, RefusesAJpegCutShortAndClosedWithAnEndMarker) {
  cv::Mat noise(480, 640, CV_8UC3);
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  for (const bool progressive : {false, true}) {
    std::vector<uint8_t> jpeg;
    ASSERT_TRUE(cv::imencode(".jpg", noise, jpeg, {cv::IMWRITE_JPEG_PROGRESSIVE, progressive}));
    EXPECT_EQ(DecodePhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels).upright.size(),
              noise.size());
    std::vector<uint8_t> cut(jpeg.begin(), jpeg.begin() + static_cast<long>(jpeg.size() * 6 / 10));
    cut.push_back(0xFF);
    cut.push_back(0xD9);
    EXPECT_EQ(ProblemOf(cut, kMaxPhotoMegapixels), PhotoProblem::kCorrupt) << progressive;
    try {
      DecodePhoto(cut.data(), cut.size(), kMaxPhotoMegapixels);
    } catch (const PhotoRejected& e) {
      EXPECT_NE(std::string(e.what()).find("Corrupt JPEG data"), std::string::npos) << e.what();
    }
  }
}

// Not every libjpeg warning means invented pixels: an unknown JFIF revision (written by some
// encoders) draws "unknown JFIF revision number" but leaves every pixel, and such a photo is
// decoded as it is.
TEST(DecodePhoto, AcceptsAJpegWhoseOnlyWarningLeavesThePixels) {
  cv::Mat noise(480, 640, CV_8UC3);
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", noise, jpeg));
  // SOI, APP0 marker and length, "JFIF\0", then the major revision.
  ASSERT_TRUE(jpeg.size() > 12 && jpeg[3] == 0xE0 && std::memcmp(&jpeg[6], "JFIF", 5) == 0);
  ASSERT_EQ(jpeg[11], 1);
  std::vector<uint8_t> revised = jpeg;
  revised[11] = 3;
  const cv::Mat whole = DecodePhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels).upright;
  const cv::Mat decoded = DecodePhoto(revised.data(), revised.size(), kMaxPhotoMegapixels).upright;
  ASSERT_EQ(decoded.size(), whole.size());
  EXPECT_EQ(cv::norm(decoded, whole, cv::NORM_INF), 0.0);
}

TEST(ExifOrientation, GarbageAndAbsentTagsGiveOne) {
  EXPECT_EQ(ExifOrientation(nullptr, 0), 1);
  const std::vector<uint8_t> soi = {0xFF, 0xD8, 0xFF, 0xE1, 0x00};
  EXPECT_EQ(ExifOrientation(soi.data(), soi.size()), 1);
  ExifFields fields;
  fields.orientation = 9;  // out of range
  const std::vector<uint8_t> jpeg = JpegWithExif(16, 16, fields);
  EXPECT_EQ(ExifOrientation(jpeg.data(), jpeg.size()), 1);
  fields.orientation = 8;
  fields.order = EXIF_BYTE_ORDER_MOTOROLA;
  const std::vector<uint8_t> big_endian = JpegWithExif(16, 16, fields);
  EXPECT_EQ(ExifOrientation(big_endian.data(), big_endian.size()), 8);
  for (size_t cut = 0; cut < big_endian.size(); cut += 7) {
    const int code = ExifOrientation(big_endian.data(), cut);
    EXPECT_TRUE(code == 1 || code == 8) << cut;
  }
}

TEST(ReadPhotoFile, NamesTheFileInItsErrors) {
  try {
    ReadPhotoFile("/nonexistent/photo.jpg", kMaxPhotoMegapixels);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/photo.jpg"), std::string::npos);
  }
}

}  // namespace
}  // namespace sightmap::identify
