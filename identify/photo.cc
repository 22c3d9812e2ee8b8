#include "identify/photo.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
// After <cstdio>: jpeglib.h uses FILE and size_t without including their headers.
#include <jpeglib.h>
// After jpeglib.h, which it extends: the warning codes.
#include <jerror.h>

#include "core/input_file.h"
#include "identify/exif.h"

namespace sightmap::identify {
namespace {

// Aspect ratios closer than this are the same camera at another resolution; farther, a crop or
// another camera, which no scaling turns into the photo's.
constexpr double kAspectTolerance = 0.01;

bool SameAspect(int width_a, int height_a, int width_b, int height_b) {
  const double a = static_cast<double>(width_a) / height_a;
  const double b = static_cast<double>(width_b) / height_b;
  return std::abs(a - b) <= kAspectTolerance * b;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

void CheckCamera(const Intrinsics& intrinsics, const char* what) {
  std::string why;
  if (!intrinsics.Check(&why)) SIGHTMAP_THROW(InvalidArgument, what << ": " << why);
}

// `intrinsics` at the size (width, height), or an error naming `what` when the aspect differs.
Intrinsics FitTo(const Intrinsics& intrinsics, int width, int height, const std::string& what) {
  CheckCamera(intrinsics, what.c_str());
  if (intrinsics.width == width && intrinsics.height == height) return intrinsics;
  if (!SameAspect(intrinsics.width, intrinsics.height, width, height))
    SIGHTMAP_THROW(InvalidArgument,
                   what << " describe a " << SizeText(intrinsics.width, intrinsics.height)
                        << " image but the photo is " << SizeText(width, height)
                        << ": another aspect ratio is another camera or a crop, not a scaling");
  return intrinsics.Scaled(width, height);
}

// libjpeg's error manager, extended: a fatal error jumps back to the decoder with its message, and
// a warning (corrupt or missing entropy data, which libjpeg decodes as grey and only reports on
// stderr) is kept instead of printed, so the decoder can refuse the image with it.
struct StrictJpegErrors {
  jpeg_error_mgr manager;  // first: libjpeg hands back a pointer to it
  std::jmp_buf fatal;
  char message[JMSG_LENGTH_MAX] = "";
  bool warned = false;
};

void JpegFatal(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<StrictJpegErrors*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, errors->message);
  std::longjmp(errors->fatal, 1);
}

// The warnings that mean pixels were invented: entropy data cut short or damaged. The others leave
// the image whole and are not refused: extraneous bytes before a marker (which some cameras and
// editors write), an unknown JFIF version, an odd Adobe transform.
bool InventsPixels(int code) {
  switch (code) {
    case JWRN_JPEG_EOF:
    case JWRN_HIT_MARKER:
    case JWRN_MUST_RESYNC:
    case JWRN_NOT_SEQUENTIAL:
    case JWRN_HUFF_BAD_CODE:
    case JWRN_BOGUS_PROGRESSION:
      return true;
    default:
      return false;
  }
}

void JpegMessage(j_common_ptr cinfo, int level) {
  if (level >= 0) return;  // trace messages
  ++cinfo->err->num_warnings;
  if (!InventsPixels(cinfo->err->msg_code)) return;
  auto* errors = reinterpret_cast<StrictJpegErrors*>(cinfo->err);
  if (!errors->warned) (*cinfo->err->format_message)(cinfo, errors->message);
  errors->warned = true;
}

// Runs libjpeg on `data` into `*image` (BGR, or CMYK inks when the JPEG has them). Returns false
// after a fatal error, with its message in `errors`. Kept free of C++ objects of its own: the
// error exit jumps back here past libjpeg's frames, and only `cinfo` (in memory) is used after.
bool RunLibjpeg(const uint8_t* data, size_t size, StrictJpegErrors* errors, cv::Mat* image,
                bool* cmyk) {
  jpeg_decompress_struct cinfo;
  std::memset(&cinfo, 0, sizeof(cinfo));
  cinfo.err = jpeg_std_error(&errors->manager);
  errors->manager.error_exit = JpegFatal;
  errors->manager.emit_message = JpegMessage;
  if (setjmp(errors->fatal) != 0) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  // Adobe CMYK (and YCCK) has no RGB output in libjpeg: read its inks, converted by the caller.
  *cmyk = cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK;
  cinfo.out_color_space = *cmyk ? JCS_CMYK : JCS_EXT_BGR;
  jpeg_start_decompress(&cinfo);
  image->create(static_cast<int>(cinfo.output_height), static_cast<int>(cinfo.output_width),
                *cmyk ? CV_8UC4 : CV_8UC3);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = image->ptr<uint8_t>(static_cast<int>(cinfo.output_scanline));
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return true;
}

// Decodes a JPEG to BGR as cv::imdecode does (the same library with the same defaults: the same
// pixels), but refuses what libjpeg only warns about on stderr: data cut short and closed with an
// end marker, or damaged inside, decodes with invented grey or garbage, which must never be
// matched. Nothing is printed.
cv::Mat DecodeJpegStrictly(const uint8_t* data, size_t size) {
  StrictJpegErrors errors;
  cv::Mat image;
  bool cmyk = false;
  if (!RunLibjpeg(data, size, &errors, &image, &cmyk)) {
    throw PhotoRejected(PhotoProblem::kCorrupt,
                        std::string("the jpeg does not decode: ") + errors.message);
  }
  if (errors.warned) {
    throw PhotoRejected(PhotoProblem::kCorrupt,
                        std::string("the jpeg is corrupt: ") + errors.message +
                            " (decoders fill what is missing with grey); send the whole file");
  }
  if (!cmyk) return image;
  // As OpenCV converts Adobe's (inverted) inks.
  cv::Mat bgr(image.rows, image.cols, CV_8UC3);
  for (int v = 0; v < image.rows; ++v) {
    const uint8_t* ink = image.ptr<uint8_t>(v);
    uint8_t* out = bgr.ptr<uint8_t>(v);
    for (int u = 0; u < image.cols; ++u, ink += 4, out += 3) {
      const int k = ink[3];
      out[2] = static_cast<uint8_t>(k - (((255 - ink[0]) * k) >> 8));
      out[1] = static_cast<uint8_t>(k - (((255 - ink[1]) * k) >> 8));
      out[0] = static_cast<uint8_t>(k - (((255 - ink[2]) * k) >> 8));
    }
  }
  return bgr;
}

}  // namespace

const char* ToString(IntrinsicsSource source) {
  switch (source) {
    case IntrinsicsSource::kGiven:
      return "given";
    case IntrinsicsSource::kCalibration:
      return "calibration";
    case IntrinsicsSource::kExif:
      return "exif";
    case IntrinsicsSource::kEstimated:
      return "estimated";
  }
  return "unknown";
}

PhotoOrientation PhotoOrientation::FromExif(int code) {
  // Codes 1-8 as clockwise quarter turns then a mirror: 2 mirror; 3 half turn; 4 half turn and
  // mirror (a vertical flip); 5 a quarter and mirror (transpose); 6 a quarter; 7 three quarters
  // and mirror (transverse); 8 three quarters.
  static constexpr int kTurns[9] = {0, 0, 0, 2, 2, 1, 1, 3, 3};
  static constexpr bool kMirrored[9] = {false, false, true, false, true, true, false, true, false};
  PhotoOrientation orientation;
  if (code < 1 || code > 8) return orientation;
  orientation.exif_code = code;
  orientation.quarter_turns_cw = kTurns[code];
  orientation.mirrored = kMirrored[code];
  return orientation;
}

cv::Mat TurnClockwise(const cv::Mat& stored, int quarter_turns) {
  cv::Mat turned;
  switch (((quarter_turns % 4) + 4) % 4) {
    case 0:
      return stored;
    case 1:
      cv::rotate(stored, turned, cv::ROTATE_90_CLOCKWISE);
      break;
    case 2:
      cv::rotate(stored, turned, cv::ROTATE_180);
      break;
    default:
      cv::rotate(stored, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
      break;
  }
  return turned;
}

Intrinsics TurnClockwise(const Intrinsics& stored, int quarter_turns) {
  Intrinsics k = stored;
  for (int turn = 0; turn < ((quarter_turns % 4) + 4) % 4; ++turn) {
    // A quarter turn clockwise sends pixel (u, v) of a W x H image to (H - 1 - v, u).
    const Intrinsics before = k;
    k.width = before.height;
    k.height = before.width;
    k.fx = before.fy;
    k.fy = before.fx;
    k.cx = (before.height - 1) - before.cy;
    k.cy = before.cx;
  }
  return k;
}

Eigen::Vector2d Photo::DisplayPixel(const Eigen::Vector2d& upright_pixel) const {
  if (!orientation.mirrored) return upright_pixel;
  return {(width() - 1) - upright_pixel.x(), upright_pixel.y()};
}

int Photo::width() const {
  return orientation.quarter_turns_cw % 2 == 0 ? stored.width : stored.height;
}

int Photo::height() const {
  return orientation.quarter_turns_cw % 2 == 0 ? stored.height : stored.width;
}

Photo InspectPhoto(const uint8_t* data, size_t size, double max_megapixels) {
  const std::optional<ImageHeader> header = ReadImageHeader(data, size);
  if (!header) {
    throw PhotoRejected(PhotoProblem::kNotAnImage, "the photo is not a JPEG or PNG image");
  }
  const double megapixels = static_cast<double>(header->pixels()) * 1e-6;
  if (megapixels > max_megapixels) {
    std::ostringstream message;
    message << "photo too large: " << SizeText(header->width, header->height) << " ("
            << std::lround(megapixels) << " megapixels), the limit is " << max_megapixels
            << "; send it downscaled (a 1280x960 or 2560x1920 photo is plenty)";
    throw PhotoRejected(PhotoProblem::kTooLarge, message.str());
  }
  if (std::min(header->width, header->height) < kMinPhotoSidePx) {
    throw PhotoRejected(PhotoProblem::kTooSmall,
                        "photo too small: " + SizeText(header->width, header->height) +
                            ", each side must be at least " + std::to_string(kMinPhotoSidePx) +
                            " px to hold features to match; send the full photo, not a thumbnail");
  }
  if (!ImageIsComplete(data, size, header->format)) {
    throw PhotoRejected(PhotoProblem::kTruncated,
                        std::string("the ") + ToString(header->format) +
                            " is truncated (it has no end marker): the upload or copy was cut "
                            "short, send the whole file");
  }
  Photo photo;
  photo.stored = *header;
  if (header->format == ImageFormat::kJpeg) {
    const ExifFacts exif = ReadExifFacts(data, size);
    photo.orientation = PhotoOrientation::FromExif(exif.orientation);
    photo.exif_focal_35mm = exif.focal_35mm;
  }
  return photo;
}

void DecodePixels(const uint8_t* data, size_t size, Photo* photo) {
  // The orientation is applied here, explicitly, so the pixels and the intrinsics turn together.
  cv::Mat stored;
  if (photo->stored.format == ImageFormat::kJpeg) {
    stored = DecodeJpegStrictly(data, size);  // throws PhotoRejected with libjpeg's reason
  } else {
    const cv::Mat encoded(1, static_cast<int>(std::min<size_t>(size, INT_MAX)), CV_8UC1,
                          const_cast<uint8_t*>(data));
    try {
      stored = cv::imdecode(encoded, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
    } catch (const cv::Exception&) {
      stored.release();
    }
  }
  if (stored.empty() || stored.cols != photo->stored.width || stored.rows != photo->stored.height) {
    throw PhotoRejected(
        PhotoProblem::kCorrupt,
        std::string("the ") + ToString(photo->stored.format) + " does not decode (corrupt data)");
  }
  photo->upright = TurnClockwise(stored, photo->orientation.quarter_turns_cw);
}

Photo DecodePhoto(const uint8_t* data, size_t size, double max_megapixels) {
  Photo photo = InspectPhoto(data, size, max_megapixels);
  DecodePixels(data, size, &photo);
  return photo;
}

Photo ReadPhotoFile(const std::string& path, double max_megapixels) {
  std::ifstream in = OpenInputFile(path, "photo", std::ios::binary);
  if (!in.is_open())
    SIGHTMAP_THROW(InvalidArgument,
                   "cannot read photo " << path << ": no such file or no permission");
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (in.bad()) SIGHTMAP_THROW(InvalidArgument, "cannot read photo " << path << ": read error");
  try {
    return DecodePhoto(bytes.data(), bytes.size(), max_megapixels);
  } catch (const PhotoRejected& e) {
    throw PhotoRejected(e.problem(), path + ": " + e.what());
  }
}

ChosenIntrinsics ChooseIntrinsics(const Photo& photo, const IntrinsicsHint& hint) {
  ChosenIntrinsics chosen;
  if (hint.upright) {
    chosen.intrinsics = FitTo(*hint.upright, photo.width(), photo.height(), "the intrinsics");
    chosen.source = IntrinsicsSource::kGiven;
  } else if (hint.sensor) {
    // A calibration describes the sensor's pixels, which the file stores unturned.
    const Intrinsics stored = FitTo(*hint.sensor, photo.stored.width, photo.stored.height,
                                    "the calibration's colour intrinsics");
    chosen.intrinsics = TurnClockwise(stored, photo.orientation.quarter_turns_cw);
    chosen.source = IntrinsicsSource::kCalibration;
  } else if (photo.exif_focal_35mm) {
    chosen.intrinsics =
        IntrinsicsFromFocal35mm(photo.width(), photo.height(), *photo.exif_focal_35mm);
    chosen.source = IntrinsicsSource::kExif;
  }
  return chosen;
}

}  // namespace sightmap::identify
