#include "core/image_header.h"

namespace sightmap {
namespace {

uint32_t BigEndian16(const uint8_t* p) { return (uint32_t{p[0]} << 8) | p[1]; }
uint32_t BigEndian32(const uint8_t* p) { return (BigEndian16(p) << 16) | BigEndian16(p + 2); }

std::optional<ImageHeader> ReadPng(const uint8_t* data, size_t size) {
  static constexpr uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  // Signature, then the IHDR chunk: length (13), "IHDR", width, height (big-endian).
  if (size < 26) return std::nullopt;
  for (int i = 0; i < 8; ++i) {
    if (data[i] != kSignature[i]) return std::nullopt;
  }
  if (data[12] != 'I' || data[13] != 'H' || data[14] != 'D' || data[15] != 'R') return std::nullopt;
  const uint32_t width = BigEndian32(data + 16);
  const uint32_t height = BigEndian32(data + 20);
  // PNG limits both to 2^31 - 1.
  if (width == 0 || height == 0 || width > 0x7FFFFFFFu || height > 0x7FFFFFFFu) {
    return std::nullopt;
  }
  ImageHeader header{ImageFormat::kPng, static_cast<int>(width), static_cast<int>(height)};
  header.bits = data[24];
  switch (data[25]) {  // colour type
    case 0:
      header.channels = 1;
      break;
    case 2:
      header.channels = 3;
      break;
    case 3:  // palette entries are 8-bit RGB whatever the index width
      header.channels = 3;
      header.bits = 8;
      break;
    case 4:
      header.channels = 2;
      break;
    case 6:
      header.channels = 4;
      break;
    default:
      return std::nullopt;
  }
  return header;
}

bool IsStartOfFrame(uint8_t marker) {
  // SOF0-SOF15 except DHT (C4), JPG (C8) and DAC (CC), which share the range.
  return marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
}

std::optional<ImageHeader> ReadJpeg(const uint8_t* data, size_t size) {
  if (size < 4 || data[0] != 0xFF || data[1] != 0xD8) return std::nullopt;
  size_t at = 2;
  while (at < size) {
    if (data[at] != 0xFF) return std::nullopt;  // segments follow each other without gaps
    // Any number of 0xFF fill bytes may precede a marker.
    while (at < size && data[at] == 0xFF) ++at;
    if (at >= size) return std::nullopt;
    const uint8_t marker = data[at++];
    // Markers without a length: TEM, RST0-7, SOI; EOI or SOS before a frame header means none.
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) continue;
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;
    if (at + 2 > size) return std::nullopt;
    const size_t length = BigEndian16(data + at);  // includes its own two bytes
    if (length < 2) return std::nullopt;
    if (IsStartOfFrame(marker)) {
      // Length (2), precision (1), height (2), width (2), components (1).
      if (length < 8 || at + 8 > size) return std::nullopt;
      const int height = static_cast<int>(BigEndian16(data + at + 3));
      const int width = static_cast<int>(BigEndian16(data + at + 5));
      // A zero height means "given by a DNL marker later": rare, and not worth decoding blind.
      if (width == 0 || height == 0) return std::nullopt;
      ImageHeader header{ImageFormat::kJpeg, width, height};
      header.bits = data[at + 2];
      header.channels = data[at + 7];
      return header;
    }
    at += length;
  }
  return std::nullopt;
}

}  // namespace

const char* ToString(ImageFormat format) { return format == ImageFormat::kJpeg ? "jpeg" : "png"; }

std::optional<ImageHeader> ReadImageHeader(const uint8_t* data, size_t size) {
  if (data == nullptr) return std::nullopt;
  if (auto png = ReadPng(data, size)) return png;
  return ReadJpeg(data, size);
}

bool ImageIsComplete(const uint8_t* data, size_t size, ImageFormat format) {
  if (data == nullptr || size < 4) return false;
  if (format == ImageFormat::kPng) {
    // The IEND chunk whole (length 0, "IEND", its 4-byte CRC); a few trailing bytes are tolerated.
    for (size_t i = size > 64 ? size - 64 : 0; i + 8 <= size; ++i) {
      if (data[i] == 'I' && data[i + 1] == 'E' && data[i + 2] == 'N' && data[i + 3] == 'D') {
        return true;
      }
    }
    return false;
  }
  // Entropy-coded data stuffs every FF with 00, so FF DA and FF D9 there are markers.
  size_t last_scan = size;
  for (size_t i = size - 1; i > 0; --i) {
    if (data[i - 1] == 0xFF && data[i] == 0xDA) {
      last_scan = i + 1;
      break;
    }
  }
  if (last_scan == size) return false;
  for (size_t i = last_scan; i + 1 < size; ++i) {
    if (data[i] == 0xFF && data[i + 1] == 0xD9) return true;
  }
  return false;
}

}  // namespace sightmap
