// libFuzzer harness: a phone photo's bytes as `locate` and `serve` take them: the header reader,
// the end-marker check, the EXIF focal length and orientation, and the decoder with the
// intrinsics rule. Photos above 4 megapixels are refused from their header, which keeps the
// decoder's allocations small. A sightmap::Error is the right answer to bad bytes; anything else
// is a finding.
#include <cstddef>
#include <cstdint>

#include "core/check.h"
#include "core/image_header.h"
#include "identify/exif.h"
#include "identify/photo.h"

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
  } catch (const Error&) {
  }
  return 0;
}
