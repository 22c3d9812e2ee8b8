#include "identify/exif.h"

#include <libexif/exif-data.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>

#include "core/check.h"
#include "core/image_header.h"
#include "core/input_file.h"

namespace sightmap::identify {
namespace {

// The 36 x 24 mm film frame's diagonal, on which 35 mm equivalence is defined [mm].
const double kFilmDiagonalMm = std::hypot(36.0, 24.0);
// Focal lengths outside this are taken as corrupt rather than believed [mm, 35 mm-equivalent].
constexpr double kMinPlausibleFocal35mm = 2.0;
constexpr double kMaxPlausibleFocal35mm = 5000.0;

struct ExifDataUnref {
  void operator()(ExifData* data) const { exif_data_unref(data); }
};

bool Plausible(double focal_35mm) {
  return std::isfinite(focal_35mm) && focal_35mm >= kMinPlausibleFocal35mm &&
         focal_35mm <= kMaxPlausibleFocal35mm;
}

// A tag's first value as a number, from the EXIF IFD (where the standard puts focal tags) or IFD0
// (where some writers put them); never IFD1, which describes the thumbnail.
std::optional<double> TagValue(ExifData* exif, ExifTag tag) {
  const ExifByteOrder order = exif_data_get_byte_order(exif);
  for (const ExifIfd ifd : {EXIF_IFD_EXIF, EXIF_IFD_0}) {
    ExifEntry* entry = exif_content_get_entry(exif->ifd[ifd], tag);
    if (!entry || !entry->data || entry->components < 1) continue;
    const unsigned int size = exif_format_get_size(entry->format);
    if (size == 0 || entry->size < size) continue;
    switch (entry->format) {
      case EXIF_FORMAT_SHORT:
        return exif_get_short(entry->data, order);
      case EXIF_FORMAT_LONG:
        return exif_get_long(entry->data, order);
      case EXIF_FORMAT_SLONG:
        return exif_get_slong(entry->data, order);
      case EXIF_FORMAT_RATIONAL: {
        const ExifRational r = exif_get_rational(entry->data, order);
        if (r.denominator == 0) return std::nullopt;
        return static_cast<double>(r.numerator) / r.denominator;
      }
      case EXIF_FORMAT_SRATIONAL: {
        const ExifSRational r = exif_get_srational(entry->data, order);
        if (r.denominator == 0) return std::nullopt;
        return static_cast<double>(r.numerator) / r.denominator;
      }
      default:
        return std::nullopt;
    }
  }
  return std::nullopt;
}

std::optional<double> Positive(std::optional<double> value) {
  if (value && std::isfinite(*value) && *value > 0.0) return value;
  return std::nullopt;
}

// Millimetres per FocalPlaneResolutionUnit (EXIF: 2 inch, the default; 3 cm; 4 mm, a common
// extension).
std::optional<double> UnitMm(std::optional<double> unit) {
  // Range-checked before the cast: a LONG or RATIONAL unit of billions is undefined behaviour as
  // an int (found by photo_fuzzer).
  if (unit && !(*unit >= 0.0 && *unit <= 16.0)) return std::nullopt;
  const int code = unit ? static_cast<int>(*unit) : 2;
  switch (code) {
    case 2:
      return 25.4;
    case 3:
      return 10.0;
    case 4:
      return 1.0;
    default:
      return std::nullopt;
  }
}

// FocalLength over the sensor's diagonal, scaled to the film frame's.
std::optional<double> DerivedFocal35mm(ExifData* exif, const uint8_t* data, size_t size) {
  const std::optional<double> focal_mm = Positive(TagValue(exif, EXIF_TAG_FOCAL_LENGTH));
  const std::optional<double> x_per_unit =
      Positive(TagValue(exif, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION));
  const std::optional<double> unit_mm =
      UnitMm(TagValue(exif, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT));
  if (!focal_mm || !x_per_unit || !unit_mm) return std::nullopt;
  // Square sensor pixels unless the file says otherwise.
  const double y_per_unit =
      Positive(TagValue(exif, EXIF_TAG_FOCAL_PLANE_Y_RESOLUTION)).value_or(*x_per_unit);
  // The focal-plane resolutions refer to the image as recorded (PixelX/YDimension); without
  // those, the JPEG's own size.
  std::optional<double> width = Positive(TagValue(exif, EXIF_TAG_PIXEL_X_DIMENSION));
  std::optional<double> height = Positive(TagValue(exif, EXIF_TAG_PIXEL_Y_DIMENSION));
  if (!width || !height) {
    const std::optional<ImageHeader> header = ReadImageHeader(data, size);
    if (!header) return std::nullopt;
    width = header->width;
    height = header->height;
  }
  const double sensor_width_mm = *width / *x_per_unit * *unit_mm;
  const double sensor_height_mm = *height / y_per_unit * *unit_mm;
  const double sensor_diagonal_mm = std::hypot(sensor_width_mm, sensor_height_mm);
  if (!(sensor_diagonal_mm > 0.0)) return std::nullopt;
  return *focal_mm * kFilmDiagonalMm / sensor_diagonal_mm;
}

}  // namespace

ExifFacts ReadExifFacts(const uint8_t* data, size_t size) {
  ExifFacts facts;
  // Only JPEGs (SOI first): anything else is not worth handing to libexif's scanner.
  if (!data || size < 4 || data[0] != 0xFF || data[1] != 0xD8) return facts;
  std::unique_ptr<ExifData, ExifDataUnref> exif(exif_data_new());
  if (!exif) return facts;
  // Read what the file says; "following the specification" would add mandatory tags with
  // made-up defaults.
  exif_data_unset_option(exif.get(), EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  // The APP1 segment sits near the start, so a body past libexif's unsigned size loses nothing.
  exif_data_load_data(exif.get(), data,
                      static_cast<unsigned int>(std::min<size_t>(size, UINT_MAX)));

  const ExifEntry* orientation =
      exif_content_get_entry(exif->ifd[EXIF_IFD_0], EXIF_TAG_ORIENTATION);
  if (orientation && orientation->data && orientation->format == EXIF_FORMAT_SHORT &&
      orientation->size >= 2) {
    const int code = exif_get_short(orientation->data, exif_data_get_byte_order(exif.get()));
    if (code >= 1 && code <= 8) facts.orientation = code;
  }

  const std::optional<double> recorded = TagValue(exif.get(), EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM);
  if (recorded && Plausible(*recorded)) {  // 0 means "unknown" in EXIF
    facts.focal_35mm = recorded;
  } else if (const std::optional<double> derived = DerivedFocal35mm(exif.get(), data, size);
             derived && Plausible(*derived)) {
    facts.focal_35mm = derived;
  }
  return facts;
}

std::optional<double> ExifFocalLength35mm(const uint8_t* data, size_t size) {
  return ReadExifFacts(data, size).focal_35mm;
}

int ExifOrientation(const uint8_t* data, size_t size) {
  return ReadExifFacts(data, size).orientation;
}

std::optional<double> ExifFocalLength35mm(const std::vector<uint8_t>& jpeg) {
  return ExifFocalLength35mm(jpeg.data(), jpeg.size());
}

std::optional<double> ExifFocalLength35mmOfFile(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "photo", std::ios::binary);
  if (!in.is_open()) return std::nullopt;
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  return ExifFocalLength35mm(bytes);
}

Intrinsics IntrinsicsFromFocal35mm(int width, int height, double focal_35mm) {
  if (width <= 0 || height <= 0 || !(focal_35mm > 0.0) || !std::isfinite(focal_35mm)) {
    SIGHTMAP_THROW(InvalidArgument,
                   "intrinsics from a 35 mm-equivalent focal length need a "
                   "positive image size and focal length, got "
                       << width << "x" << height << " px at " << focal_35mm << " mm");
  }
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = focal_35mm * std::hypot(width, height) / kFilmDiagonalMm;
  k.fy = k.fx;
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  return k;
}

}  // namespace sightmap::identify
