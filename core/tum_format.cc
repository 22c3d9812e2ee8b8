#include "core/tum_format.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/atomic_file.h"
#include "core/check.h"
#include "core/input_file.h"

namespace sightmap {
namespace {

constexpr int64_t kMaxSeconds = 9'000'000'000;  // keeps seconds * 1e9 inside int64_t

bool AllDigits(const std::string& text) {
  return std::all_of(text.begin(), text.end(),
                     [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
}

}  // namespace

bool ParseFiniteDouble(const std::string& text, double* value) {
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size() && std::isfinite(*value);
}

void ThrowMalformedLine(const std::string& path, int line_number, const std::string& line,
                        const std::string& expected) {
  SIGHTMAP_THROW(Error, path << ":" << line_number << ": expected " << expected << " but found \""
                             << line << "\"; fix or delete the line");
}

bool ParseTimestampNs(const std::string& text, TimestampNs* ns) {
  const bool negative = !text.empty() && text[0] == '-';
  const std::string digits = negative ? text.substr(1) : text;
  const size_t dot = digits.find('.');
  const std::string whole = digits.substr(0, dot);
  const std::string fraction = dot == std::string::npos ? std::string() : digits.substr(dot + 1);
  if ((!whole.empty() || !fraction.empty()) && AllDigits(whole) && AllDigits(fraction) &&
      whole.size() <= 10) {
    const int64_t seconds = whole.empty() ? 0 : std::stoll(whole);
    if (seconds > kMaxSeconds) return false;
    int64_t nanos = 0;
    for (size_t i = 0; i < 9; ++i) {
      nanos = nanos * 10 + (i < fraction.size() ? fraction[i] - '0' : 0);
    }
    if (fraction.size() > 9 && fraction[9] >= '5') ++nanos;
    const int64_t magnitude = seconds * 1'000'000'000 + nanos;
    *ns = negative ? -magnitude : magnitude;
    return true;
  }
  // Anything else a float parser takes (exponents); precision is then the writer's problem.
  char* end = nullptr;
  const long double seconds = std::strtold(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(seconds) ||
      std::fabs(seconds) > static_cast<long double>(kMaxSeconds)) {
    return false;
  }
  *ns = std::llround(seconds * 1e9L);
  return true;
}

std::string FormatTimestamp(TimestampNs ns) {
  const bool negative = ns < 0;
  const uint64_t magnitude = negative ? 0 - static_cast<uint64_t>(ns) : static_cast<uint64_t>(ns);
  char text[48];
  std::snprintf(text, sizeof(text), "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "",
                magnitude / 1000000000u, magnitude % 1000000000u);
  return text;
}

void ForEachTumLine(std::istream& in,
                    const std::function<void(const std::vector<std::string>&, int,
                                             const std::string&)>& fields_of_line) {
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::string spaced = line;
    std::replace(spaced.begin(), spaced.end(), ',', ' ');
    std::istringstream stream(spaced);
    std::vector<std::string> fields;
    for (std::string field; stream >> field;) fields.push_back(field);
    if (fields.empty() || fields.front().front() == '#') continue;
    fields_of_line(fields, line_number, line);
  }
}

std::vector<StampedPose> ReadTumTrajectory(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "trajectory");
  SIGHTMAP_CHECK(in.is_open(), "cannot read trajectory " << path << ": check that it exists");
  std::vector<StampedPose> poses;
  ForEachTumLine(
      in, [&](const std::vector<std::string>& tokens, int line_number, const std::string& line) {
        StampedPose pose;
        std::array<double, 7> v{};
        bool ok = tokens.size() == 8 && ParseTimestampNs(tokens[0], &pose.timestamp_ns);
        for (size_t i = 0; ok && i < v.size(); ++i) ok = ParseFiniteDouble(tokens[i + 1], &v[i]);
        const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // the file's order is x y z w
        if (!ok || !(q.norm() > 1e-6)) {
          ThrowMalformedLine(path, line_number, line,
                             "\"timestamp tx ty tz qx qy qz qw\" with a non-zero quaternion");
        }
        pose.world_from_cam.linear() = q.normalized().toRotationMatrix();
        pose.world_from_cam.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
        poses.push_back(pose);
      });
  return poses;
}

void WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses,
                        const std::string& comment) {
  AtomicFile file(path);
  std::ostream& out = file.out();
  if (!comment.empty()) out << "# " << comment << "\n";
  out << "# timestamp tx ty tz qx qy qz qw (world_from_cam, TUM RGB-D format)\n";
  char line[256];
  for (const StampedPose& pose : poses) {
    const Eigen::Vector3d t = pose.world_from_cam.translation();
    const Eigen::Quaterniond q(pose.world_from_cam.rotation());
    std::snprintf(line, sizeof(line), " %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", t.x(), t.y(),
                  t.z(), q.x(), q.y(), q.z(), q.w());
    out << FormatTimestamp(pose.timestamp_ns) << line;
  }
  file.Commit();
}

}  // namespace sightmap
