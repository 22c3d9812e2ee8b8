#include "capture/oni_file.h"

#include <array>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <vector>

#include "core/check.h"

namespace sightmap::capture {
namespace {

// OpenNI 1 record types (DataRecords.h in OpenNI 1.5) and node types (XnTypes.h).
constexpr uint32_t kRecordIntProperty = 0x03;
constexpr uint32_t kRecordNewData = 0x0A;
constexpr uint32_t kRecordEnd = 0x0B;
constexpr uint32_t kRecordNodeAdded = 0x0D;
constexpr uint32_t kNodeTypeDepth = 2;

// Record header: "NIR\0", type, node id, size of header plus fields, payload size, undo position.
constexpr size_t kRecordHeaderSize = 28;
constexpr size_t kFileHeaderSize = 24;
// The property records come first; a recorder never writes this many before its first frame.
constexpr int kMaxRecordsScanned = 4096;

template <typename T>
T ReadLe(const char* data) {
  T value;
  std::memcpy(&value, data, sizeof(T));
  return value;
}

}  // namespace

OniFileInfo ReadOniFileInfo(const std::string& path) {
  std::error_code ec;
  SIGHTMAP_CHECK(std::filesystem::exists(path, ec), "no such recording: " << path);
  SIGHTMAP_CHECK(std::filesystem::is_regular_file(path, ec),
                 path << " is not a file: pass an .oni recording");
  const uint64_t file_size = std::filesystem::file_size(path, ec);
  SIGHTMAP_CHECK(!ec && file_size > 0, path << " is empty: it is not an OpenNI recording");
  std::ifstream in(path, std::ios::binary);
  SIGHTMAP_CHECK(in, "cannot read " << path << ": check its permissions");

  std::array<char, kFileHeaderSize> header{};
  in.read(header.data(), header.size());
  SIGHTMAP_CHECK(in.gcount() == static_cast<std::streamsize>(header.size()) &&
                     std::memcmp(header.data(), "NI10", 4) == 0,
                 path << " is not an OpenNI recording (no ONI signature): record with "
                         "OpenNI's NiViewer or with sightmap");
  OniFileInfo info;
  info.version_major = static_cast<unsigned char>(header[4]);
  info.version_minor = static_cast<unsigned char>(header[5]);
  info.version_maintenance = ReadLe<uint16_t>(header.data() + 6);
  info.max_timestamp_us = ReadLe<uint64_t>(header.data() + 12);
  SIGHTMAP_CHECK(
      !(info.version_major == 1 && info.version_minor == 0 && info.version_maintenance == 0),
      path << " is an ONI 1.0.0 recording, which OpenNI2 cannot play: convert it with "
              "OpenNI 1.x (NiViewer) or re-record it");
  SIGHTMAP_CHECK(info.max_timestamp_us != 0,
                 path << " holds no frames (its header says the recording is empty)");

  std::map<uint32_t, uint32_t> node_types;
  std::map<uint32_t, bool> alternative_view_point;
  uint64_t position = kFileHeaderSize;
  std::vector<char> fields;
  for (int record = 0; record < kMaxRecordsScanned && position < file_size; ++record) {
    std::array<char, kRecordHeaderSize> head{};
    in.seekg(static_cast<std::streamoff>(position));
    in.read(head.data(), head.size());
    SIGHTMAP_CHECK(in.gcount() == static_cast<std::streamsize>(head.size()) &&
                       std::memcmp(head.data(), "NIR", 4) == 0,
                   path << " is damaged at byte " << position << ": not an ONI record");
    const uint32_t type = ReadLe<uint32_t>(head.data() + 4);
    const uint32_t node = ReadLe<uint32_t>(head.data() + 8);
    const uint32_t fields_size = ReadLe<uint32_t>(head.data() + 12);
    const uint64_t payload_size = ReadLe<uint64_t>(head.data() + 16);
    SIGHTMAP_CHECK(fields_size >= kRecordHeaderSize && fields_size < (1u << 26) &&
                       position + fields_size + payload_size <= file_size,
                   path << " is truncated or damaged: a record at byte " << position
                        << " runs past the end of the file");
    if (type == kRecordNewData || type == kRecordEnd) break;
    if (type == kRecordNodeAdded || type == kRecordIntProperty) {
      fields.resize(fields_size - kRecordHeaderSize);
      in.read(fields.data(), static_cast<std::streamsize>(fields.size()));
      SIGHTMAP_CHECK(
          in.gcount() == static_cast<std::streamsize>(fields.size()) && fields.size() >= 4,
          path << " is damaged at byte " << position);
      const uint32_t name_size = ReadLe<uint32_t>(fields.data());
      if (name_size <= fields.size() - 4) {
        const std::string name(fields.data() + 4, strnlen(fields.data() + 4, name_size));
        const size_t after_name = 4 + name_size;
        if (type == kRecordNodeAdded && after_name + 4 <= fields.size()) {
          node_types[node] = ReadLe<uint32_t>(fields.data() + after_name);
          // Then codec, frame count, min and max timestamp, and where the recorder wrote the
          // node's seek table when it closed the file: past the end means the file was cut.
          const size_t seek_table_at = after_name + 4 + 4 + 4 + 8 + 8;
          if (seek_table_at + 8 <= fields.size()) {
            const uint64_t seek_table = ReadLe<uint64_t>(fields.data() + seek_table_at);
            SIGHTMAP_CHECK(seek_table == 0 || seek_table + kRecordHeaderSize <= file_size,
                           path << " is truncated: it ends at byte " << file_size
                                << " but its index starts at byte " << seek_table
                                << " — copy the recording again");
          }
        } else if (type == kRecordIntProperty && name == "AlternativeViewPoint" &&
                   fields.size() >= after_name + 8) {
          alternative_view_point[node] = ReadLe<uint64_t>(fields.data() + fields.size() - 8) != 0;
        }
      }
    }
    position += fields_size + payload_size;
  }
  for (const auto& [node, registered] : alternative_view_point) {
    if (node_types.count(node) && node_types[node] == kNodeTypeDepth) {
      info.depth_registered_to_color = registered;
    }
  }
  return info;
}

}  // namespace sightmap::capture
