#include "core/image_header.h"

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

namespace sightmap {
namespace {

std::vector<uint8_t> Encode(const std::string& extension, int width, int height,
                            const std::vector<int>& params = {}) {
  const cv::Mat image(height, width, CV_8UC3, cv::Scalar(20, 120, 220));
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes, params));
  return bytes;
}

std::vector<uint8_t> Cut(const std::vector<uint8_t>& bytes, size_t size) {
  return std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(size));
}

TEST(ImageIsComplete, WholePhotosPassAndCutOnesFail) {
  const std::vector<uint8_t> jpeg = Encode(".jpg", 640, 480);
  const std::vector<uint8_t> progressive =
      Encode(".jpg", 640, 480, {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  const std::vector<uint8_t> png = Encode(".png", 640, 480);
  for (const auto& [bytes, format] :
       {std::pair{jpeg, ImageFormat::kJpeg}, std::pair{progressive, ImageFormat::kJpeg},
        std::pair{png, ImageFormat::kPng}}) {
    EXPECT_TRUE(ImageIsComplete(bytes.data(), bytes.size(), format));
    for (const size_t size : {bytes.size() / 3, 2 * bytes.size() / 3, bytes.size() - 1}) {
      const std::vector<uint8_t> cut = Cut(bytes, size);
      EXPECT_FALSE(ImageIsComplete(cut.data(), cut.size(), format)) << size << " bytes";
    }
    // Bytes after the end (some cameras append a trailer) do not matter.
    std::vector<uint8_t> trailer = bytes;
    trailer.insert(trailer.end(), 16, 0);
    EXPECT_TRUE(ImageIsComplete(trailer.data(), trailer.size(), format));
  }
  const std::vector<uint8_t> text = {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'};
  EXPECT_FALSE(ImageIsComplete(text.data(), text.size(), ImageFormat::kJpeg));
  EXPECT_FALSE(ImageIsComplete(text.data(), text.size(), ImageFormat::kPng));
  EXPECT_FALSE(ImageIsComplete(nullptr, 0, ImageFormat::kJpeg));
}

TEST(ImageIsComplete, AThumbnailsEndMarkerDoesNotMakeACutPhotoWhole) {
  // An EXIF-like APP1 segment right after SOI carrying a whole little JPEG (its own scan and end
  // marker), as phones embed their thumbnail; then the photo, cut in its scan.
  const std::vector<uint8_t> thumbnail = Encode(".jpg", 16, 12);
  const std::vector<uint8_t> photo = Encode(".jpg", 640, 480);
  std::vector<uint8_t> app1 = {0xFF, 0xE1, 0, 0, 'E', 'x', 'i', 'f', 0, 0};
  app1.insert(app1.end(), thumbnail.begin(), thumbnail.end());
  const size_t length = app1.size() - 2;
  app1[2] = static_cast<uint8_t>(length >> 8);
  app1[3] = static_cast<uint8_t>(length & 0xFF);
  std::vector<uint8_t> with_thumbnail(photo.begin(), photo.begin() + 2);
  with_thumbnail.insert(with_thumbnail.end(), app1.begin(), app1.end());
  with_thumbnail.insert(with_thumbnail.end(), photo.begin() + 2, photo.end());
  ASSERT_TRUE(ReadImageHeader(with_thumbnail.data(), with_thumbnail.size()).has_value());
  EXPECT_TRUE(ImageIsComplete(with_thumbnail.data(), with_thumbnail.size(), ImageFormat::kJpeg));
  const std::vector<uint8_t> cut = Cut(with_thumbnail, with_thumbnail.size() - 200);
  EXPECT_FALSE(ImageIsComplete(cut.data(), cut.size(), ImageFormat::kJpeg));
}

TEST(ImageHeader, ReadsJpegAndPngSizes) {
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{37, 23}, {1280, 960}, {1, 1}}) {
    const std::vector<uint8_t> jpeg = Encode(".jpg", w, h);
    const auto j = ReadImageHeader(jpeg.data(), jpeg.size());
    ASSERT_TRUE(j.has_value());
    EXPECT_EQ(j->format, ImageFormat::kJpeg);
    EXPECT_EQ(j->width, w);
    EXPECT_EQ(j->height, h);
    const std::vector<uint8_t> png = Encode(".png", w, h);
    const auto p = ReadImageHeader(png.data(), png.size());
    ASSERT_TRUE(p.has_value());
    EXPECT_EQ(p->format, ImageFormat::kPng);
    EXPECT_EQ(p->width, w);
    EXPECT_EQ(p->height, h);
    EXPECT_EQ(p->pixels(), int64_t{w} * h);
    EXPECT_EQ(j->bits, 8);
    EXPECT_EQ(j->channels, 3);
    EXPECT_EQ(p->bits, 8);
    EXPECT_EQ(p->channels, 3);
  }
  // A 16-bit depth map and a grey JPEG, as RGB-D folders hold them.
  std::vector<uint8_t> depth;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(12, 16, CV_16UC1, cv::Scalar(5000)), depth));
  const auto d = ReadImageHeader(depth.data(), depth.size());
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->bits, 16);
  EXPECT_EQ(d->channels, 1);
  std::vector<uint8_t> grey;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(12, 16, CV_8UC1, cv::Scalar(90)), grey));
  EXPECT_EQ(ReadImageHeader(grey.data(), grey.size())->channels, 1);
}

TEST(ImageHeader, ProgressiveJpegAndSegmentsBeforeTheFrame) {
  const std::vector<uint8_t> progressive =
      Encode(".jpg", 64, 48, {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  const auto header = ReadImageHeader(progressive.data(), progressive.size());
  ASSERT_TRUE(header.has_value());
  EXPECT_EQ(header->width, 64);
  // An APP1 (EXIF-like) segment of 300 bytes and fill bytes inserted after SOI.
  std::vector<uint8_t> jpeg = Encode(".jpg", 50, 40);
  std::vector<uint8_t> app1 = {0xFF, 0xFF, 0xFF, 0xE1, 0x01, 0x2C};
  app1.resize(6 + 298, 0xAB);
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  const auto with_app1 = ReadImageHeader(jpeg.data(), jpeg.size());
  ASSERT_TRUE(with_app1.has_value());
  EXPECT_EQ(with_app1->width, 50);
  EXPECT_EQ(with_app1->height, 40);
}

TEST(ImageHeader, A100MegapixelClaimIsReadWithoutDecoding) {
  std::vector<uint8_t> jpeg = Encode(".jpg", 32, 32);
  // Patch the frame header to 10000x10000: the bytes no longer decode, the header still reads.
  for (size_t i = 2; i + 9 < jpeg.size(); ++i) {
    if (jpeg[i] == 0xFF && jpeg[i + 1] == 0xC0) {
      jpeg[i + 5] = 0x27;
      jpeg[i + 6] = 0x10;
      jpeg[i + 7] = 0x27;
      jpeg[i + 8] = 0x10;
      break;
    }
  }
  const auto header = ReadImageHeader(jpeg.data(), jpeg.size());
  ASSERT_TRUE(header.has_value());
  EXPECT_EQ(header->pixels(), int64_t{100'000'000});
}

TEST(ImageHeader, RejectsEverythingElseWithoutReadingPastTheEnd) {
  const std::vector<uint8_t> jpeg = Encode(".jpg", 40, 30);
  const std::vector<uint8_t> png = Encode(".png", 40, 30);
  // Every cut before the size fields gives nullopt; ASan/valgrind would catch an over-read.
  for (size_t n = 0; n < 24; ++n) {
    const std::vector<uint8_t> cut_png(png.begin(), png.begin() + static_cast<long>(n));
    EXPECT_FALSE(ReadImageHeader(cut_png.data(), cut_png.size()).has_value()) << n;
  }
  for (size_t n = 0; n < jpeg.size(); ++n) {
    const std::vector<uint8_t> cut(jpeg.begin(), jpeg.begin() + static_cast<long>(n));
    const auto header = ReadImageHeader(cut.data(), cut.size());
    if (header) {
      EXPECT_EQ(header->width, 40);
    }
  }
  const std::string text = "{\"not\": \"an image\"}";
  EXPECT_FALSE(ReadImageHeader(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
  EXPECT_FALSE(ReadImageHeader(nullptr, 0));
  const uint8_t sos_first[] = {0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x08, 1, 2, 3, 4, 5, 6};
  EXPECT_FALSE(ReadImageHeader(sos_first, sizeof(sos_first)));
  const uint8_t zero_length[] = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x00, 0xFF, 0xC0};
  EXPECT_FALSE(ReadImageHeader(zero_length, sizeof(zero_length)));
}

}  // namespace
}  // namespace sightmap
