#include "store/trajectory.h"

#include <cctype>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/atomic_file.h"
#include "core/check.h"

namespace sightmap {
namespace {

std::string FormatSeconds(TimestampNs ns) {
  const bool negative = ns < 0;
  const uint64_t magnitude = negative ? 0 - static_cast<uint64_t>(ns) : static_cast<uint64_t>(ns);
  char text[48];
  std::snprintf(text, sizeof(text), "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "",
                magnitude / 1000000000u, magnitude % 1000000000u);
  return text;
}

// "1305031102.175304" -> ns, exactly; falls back to a double for exponent notation.
bool ParseSeconds(const std::string& token, TimestampNs* ns) {
  if (token.find_first_of("eE") != std::string::npos) {
    char* end = nullptr;
    const double seconds = std::strtod(token.c_str(), &end);
    if (*end != '\0') return false;
    *ns = static_cast<TimestampNs>(std::llround(seconds * 1e9));
    return true;
  }
  size_t i = 0;
  const bool negative = !token.empty() && token[0] == '-';
  if (negative) ++i;
  int64_t whole = 0;
  int64_t fraction = 0;
  int fraction_digits = 0;
  bool any_digit = false;
  for (; i < token.size() && std::isdigit(static_cast<unsigned char>(token[i])); ++i) {
    whole = whole * 10 + (token[i] - '0');
    any_digit = true;
  }
  if (i < token.size() && token[i] == '.') {
    for (++i; i < token.size() && std::isdigit(static_cast<unsigned char>(token[i])); ++i) {
      if (fraction_digits < 9) {
        fraction = fraction * 10 + (token[i] - '0');
        ++fraction_digits;
      }
      any_digit = true;
    }
  }
  if (!any_digit || i != token.size()) return false;
  for (; fraction_digits < 9; ++fraction_digits) fraction *= 10;
  *ns = (negative ? -1 : 1) * (whole * 1000000000 + fraction);
  return true;
}

}  // namespace

void WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses) {
  AtomicFile file(path);
  std::ostream& out = file.out();
  out << "# timestamp tx ty tz qx qy qz qw (world_from_cam, TUM RGB-D format)\n";
  char line[256];
  for (const StampedPose& pose : poses) {
    const Eigen::Vector3d t = pose.world_from_cam.translation();
    const Eigen::Quaterniond q(pose.world_from_cam.rotation());
    std::snprintf(line, sizeof(line), " %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", t.x(), t.y(),
                  t.z(), q.x(), q.y(), q.z(), q.w());
    out << FormatSeconds(pose.timestamp_ns) << line;
  }
  file.Commit();
}

std::vector<StampedPose> ReadTumTrajectory(const std::string& path) {
  std::ifstream in(path);
  SIGHTMAP_CHECK(in.is_open(), "cannot read trajectory " << path << ": check that it exists");
  std::vector<StampedPose> poses;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::string stamp;
    double values[7];
    fields >> stamp;
    for (double& value : values) fields >> value;
    StampedPose pose;
    SIGHTMAP_CHECK(!fields.fail() && ParseSeconds(stamp, &pose.timestamp_ns),
                   path << ":" << line_number
                        << " is not 'timestamp tx ty tz qx qy qz qw' (TUM trajectory format)");
    const Eigen::Quaterniond q(values[6], values[3], values[4], values[5]);
    SIGHTMAP_CHECK(q.norm() > 1e-6, path << ":" << line_number << " has a zero quaternion");
    pose.world_from_cam.linear() = q.normalized().toRotationMatrix();
    pose.world_from_cam.translation() = Eigen::Vector3d(values[0], values[1], values[2]);
    poses.push_back(pose);
  }
  return poses;
}

std::vector<StampedPose> ModelTrajectory(const Model& model, bool odometry) {
  std::vector<StampedPose> poses;
  for (const KeyframeInfo& keyframe : model.Keyframes()) {
    poses.push_back(
        {keyframe.timestamp_ns, odometry ? keyframe.odom_world_from_cam : keyframe.world_from_cam});
  }
  return poses;
}

}  // namespace sightmap
