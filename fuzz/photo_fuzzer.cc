// libFuzzer harness: a phone photo's bytes as `locate` and `serve` take them: the header reader,
// the end-marker check, the EXIF focal length and orientation, and the decoder with the
// intrinsics rule, and ORB features on the pixels. Photos above 4 megapixels are refused from their
// header, which keeps the decoder's allocations small. A sightmap::Error is the right answer to bad
// bytes; anything else is a finding.
#include <cstddef>
#include <cstdint>

#include "core/check.h"
#include "core/image_header.h"
#include "identify/exif.h"
#include "identify/locator.h"
#include "identify/photo.h"
#include "slam/features.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace sightmap;
  if (const std::optional<ImageHeader> header = ReadImageHeader(data, size)) {
    ImageIsComplete(data, size, header->format);
  }
  identify::ExifFocalLength35mm(data, size);
  identify::ExifOrientation(data, size);
  try {
    const identify::Photo photo = identify::DecodePhoto(data, size, 4.0);
    identify::ChooseIntrinsics(photo, identify::IntrinsicsHint());
    identify::IntrinsicsHint sensor;
    sensor.sensor = Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
    identify::ChooseIntrinsics(photo, sensor);
    // What the locator does next: ORB on the decoded pixels (a 1-px side made OpenCV's pyramid
    // throw; the photo rule now refuses it). Kept to a megapixel so each input stays fast.
    if (photo.upright.total() <= (1u << 20)) {
      slam::ExtractFeatures(photo.upright, cv::Mat(),
                            Intrinsics::FromPinhole(photo.width(), photo.height(), 1000.0, 1000.0,
                                                    0.5 * photo.width(), 0.5 * photo.height()),
                            identify::LocatorOptions().features);
    }
  } catch (const Error&) {
  }
  return 0;
}
