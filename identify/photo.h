// A phone photo as the locator takes it: decoded, turned upright by its EXIF orientation, and
// given intrinsics by one rule. `sightmap locate`, `serve` and `eval identify` all come through
// here, so a portrait photo gets the same camera whichever way it arrives.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/check.h"
#include "core/image_header.h"

namespace sightmap::identify {

// Where a photo's intrinsics came from.
enum class IntrinsicsSource { kGiven, kCalibration, kExif, kEstimated };
const char* ToString(IntrinsicsSource source);

// How the stored pixels turn into the picture a viewer shows (the EXIF Orientation tag): a
// clockwise rotation by quarter turns, then a left-right mirror for codes 2, 4, 5 and 7.
struct PhotoOrientation {
  int exif_code = 1;         // 1-8; 1 when the file says nothing
  int quarter_turns_cw = 0;  // 0-3
  bool mirrored = false;

  // Codes outside 1-8 are taken as 1 (what viewers do).
  static PhotoOrientation FromExif(int code);
};

// An image turned clockwise by quarter turns, and the same for the camera that took it: a point
// projecting to (u, v) in `stored` projects to the turned pixel in the result.
cv::Mat TurnClockwise(const cv::Mat& stored, int quarter_turns);
Intrinsics TurnClockwise(const Intrinsics& stored, int quarter_turns);

// Why a photo was refused, so a server can answer with the fitting status.
enum class PhotoProblem { kNotAnImage, kTooLarge, kTooSmall, kTruncated, kCorrupt };

class PhotoRejected : public InvalidArgument {
 public:
  PhotoRejected(PhotoProblem problem, const std::string& message)
      : InvalidArgument(message), problem_(problem) {}
  PhotoProblem problem() const { return problem_; }

 private:
  PhotoProblem problem_;
};

struct Photo {
  ImageHeader stored;  // format and size as the file stores the pixels
  PhotoOrientation orientation;
  // BGR, turned by the orientation's rotation. Not mirrored: a mirror image is no pinhole
  // projection, so the locator works on the camera's own view and DisplayPixel() mirrors its
  // answers back.
  cv::Mat upright;
  // The EXIF 35 mm-equivalent focal length [mm], when the file has one.
  std::optional<double> exif_focal_35mm;

  // The upright picture's size [px] (known from the header, before decoding).
  int width() const;
  int height() const;
  // A pixel of `upright` in the picture a viewer shows (mirrored when the orientation says so).
  Eigen::Vector2d DisplayPixel(const Eigen::Vector2d& upright_pixel) const;
};

// The largest photo `locate` and `eval identify` decode [megapixels]: a 200-megapixel phone's
// full-size shot, 600 MB decoded. `serve` takes its limit from --max-megapixels.
constexpr double kMaxPhotoMegapixels = 200.0;

// The shortest side a photo may have [px]. ORB describes a 31x31 patch and keeps no keypoint within
// 31 px of the border, so a picture under 64 px on a side holds no feature to match (and OpenCV's
// feature pyramid shrinks a 1-px side to nothing and throws). No phone takes such a photo: under
// this it is a thumbnail or an icon, refused with that reason rather than "no features".
constexpr int kMinPhotoSidePx = 64;

// Everything DecodePhoto learns without decoding (`upright` stays empty): the cheap refusals
// (not an image, too large, too small, cut short) and the upright size, so a server can answer bad
// uploads without waiting for a decoder. Throws PhotoRejected as DecodePhoto does.
Photo InspectPhoto(const uint8_t* data, size_t size, double max_megapixels);

// Decodes the pixels of a photo InspectPhoto took from the same bytes into photo->upright.
// Throws PhotoRejected (kCorrupt) when they do not decode.
void DecodePixels(const uint8_t* data, size_t size, Photo* photo);

// InspectPhoto and DecodePixels: decodes a JPEG or PNG from memory. Throws PhotoRejected with one
// line: not a JPEG or PNG (by its bytes, whatever a file name or Content-Type says), more than
// max_megapixels (checked on the header, before decoding allocates 3 bytes a pixel), a side under
// kMinPhotoSidePx, cut short (no end marker: decoders would fill the rest with grey), or
// undecodable.
Photo DecodePhoto(const uint8_t* data, size_t size, double max_megapixels);
// The same for a file; also throws InvalidArgument when it cannot be read.
Photo ReadPhotoFile(const std::string& path, double max_megapixels);

// What a caller knows of the photo's camera beside the photo's own EXIF.
struct IntrinsicsHint {
  // Of the upright photo (as a viewer shows it): at its resolution, or at another of the same
  // aspect ratio (then scaled).
  std::optional<Intrinsics> upright;
  // Of the camera's stored pixels (a calibration file's colour block, landscape for a phone):
  // scaled to the stored size, then turned with the photo.
  std::optional<Intrinsics> sensor;
};

struct ChosenIntrinsics {
  std::optional<Intrinsics> intrinsics;  // of Photo::upright; nullopt: the locator estimates
  IntrinsicsSource source = IntrinsicsSource::kEstimated;
};

// The one rule: given intrinsics, else the calibration's, else the EXIF focal length's, else
// none (estimated). Throws InvalidArgument when a hint does not fit the photo (another aspect
// ratio, or not a valid camera).
ChosenIntrinsics ChooseIntrinsics(const Photo& photo, const IntrinsicsHint& hint);

}  // namespace sightmap::identify
