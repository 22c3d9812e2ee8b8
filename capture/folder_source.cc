#include "capture/folder_source.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/calibration.h"
#include "core/atomic_file.h"
#include "core/check.h"
#include "core/image_header.h"
#include "core/input_file.h"
#include "core/tum_format.h"

namespace sightmap::capture {
namespace {

namespace fs = std::filesystem;

// TUM depth PNGs hold 5000 units per metre, i.e. 5 per millimetre.
constexpr double kTumDepthUnitsPerMm = 5.0;
// Longest gap between two TUM ground-truth poses that is still interpolated. The mocap runs at
// 100 Hz, so this bridges ~9 lost samples; across longer drop-outs a hand-held camera turns too far
// for linear interpolation to stay within the ground truth's own accuracy.
constexpr int64_t kMaxGroundTruthGapNs = 100'000'000;
// 3DMatch frames carry no timestamps; its Kinect-class sensors recorded at 30 Hz.
constexpr int64_t kThreeDMatchFramePeriodNs = 33'333'333;
constexpr double kThreeDMatchNominalFps = 30.0;
// 7-Scenes marks pixels without depth with the largest 16-bit value instead of 0.
constexpr uint16_t kSevenScenesNoDepth = 65535;

template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream stream;
  (stream << ... << args);
  return stream.str();
}

std::string FormatMs(int64_t ns) { return StrCat(static_cast<double>(ns) * 1e-6, " ms"); }

std::string FormatIntrinsics(const Intrinsics& k) {
  return StrCat("fx = ", k.fx, ", fy = ", k.fy, ", cx = ", k.cx, ", cy = ", k.cy, " at ", k.width,
                "x", k.height);
}

enum class DepthEncoding {
  kTum5000PerMetre,
  kMillimetres,
};

// One frame a folder source will deliver.
struct FolderFrame {
  std::string color_path;
  std::string depth_path;
  TimestampNs timestamp_ns = 0;
  std::optional<Eigen::Isometry3d> world_from_cam;
};

// ------------------------------------------------------------------------------------------------
// Text files

// Calls parse(tokens, line_number, line) for every line that is neither blank nor a comment.
// Commas separate fields too, as in TUM's own tools.
template <typename ParseFn>
void ForEachDataLine(const fs::path& path, ParseFn&& parse) {
  std::ifstream in = OpenInputFile(path.string(), "list");
  SIGHTMAP_CHECK(in, "cannot read " << path.string() << "; check that the file is readable");
  ForEachTumLine(in, parse);
}

// 3DMatch marks a frame without a pose by a matrix of -inf: infinities are numbers here.
bool ParseNumberOrInfinity(const std::string& text, double* value) {
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size() && !std::isnan(*value);
}

bool AllDigits(const std::string& text) {
  return std::all_of(text.begin(), text.end(),
                     [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
}

struct TimedFile {
  int64_t ns = 0;
  std::string file;
  int line = 0;
};

// rgb.txt / depth.txt, sorted by time.
std::vector<TimedFile> ReadTumFileList(const fs::path& path) {
  std::vector<TimedFile> list;
  ForEachDataLine(
      path, [&](const std::vector<std::string>& tokens, int line_number, const std::string& line) {
        TimedFile entry;
        if (tokens.size() != 2 || !ParseTimestampNs(tokens[0], &entry.ns)) {
          ThrowMalformedLine(path.string(), line_number, line,
                             "\"timestamp filename\" (seconds, then a path)");
        }
        entry.file = tokens[1];
        entry.line = line_number;
        list.push_back(std::move(entry));
      });
  std::stable_sort(list.begin(), list.end(),
                   [](const TimedFile& a, const TimedFile& b) { return a.ns < b.ns; });
  return list;
}

struct GroundTruthSample {
  int64_t ns = 0;
  Eigen::Vector3d translation;
  Eigen::Quaterniond rotation;
};

std::vector<GroundTruthSample> ReadTumGroundTruth(const fs::path& path) {
  std::vector<GroundTruthSample> samples;
  for (const StampedPose& pose : ReadTumTrajectory(path.string())) {
    samples.push_back({pose.timestamp_ns, pose.world_from_cam.translation(),
                       Eigen::Quaterniond(pose.world_from_cam.linear())});
  }
  std::stable_sort(
      samples.begin(), samples.end(),
      [](const GroundTruthSample& a, const GroundTruthSample& b) { return a.ns < b.ns; });
  return samples;
}

// Linear in translation, slerp in rotation, between the poses bracketing `ns`.
std::optional<Eigen::Isometry3d> InterpolateGroundTruth(
    const std::vector<GroundTruthSample>& samples, int64_t ns) {
  const auto after =
      std::lower_bound(samples.begin(), samples.end(), ns,
                       [](const GroundTruthSample& sample, int64_t t) { return sample.ns < t; });
  if (after == samples.end()) return std::nullopt;
  Eigen::Vector3d translation;
  Eigen::Quaterniond rotation;
  if (after->ns == ns) {
    translation = after->translation;
    rotation = after->rotation;
  } else {
    if (after == samples.begin()) return std::nullopt;
    const GroundTruthSample& before = *std::prev(after);
    const int64_t gap = after->ns - before.ns;
    if (gap > kMaxGroundTruthGapNs) return std::nullopt;
    const double alpha = static_cast<double>(ns - before.ns) / static_cast<double>(gap);
    translation = (1.0 - alpha) * before.translation + alpha * after->translation;
    rotation = before.rotation.slerp(alpha, after->rotation).normalized();
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation.toRotationMatrix();
  pose.translation() = translation;
  return pose;
}

// Each depth frame with the nearest unused colour frame within `tolerance_ns`, greedily by the
// smallest time difference (TUM's associate.py). Both lists are sorted, so each depth frame's
// candidates form a window of the colour list, which avoids associate.py's all-pairs list.
// Returns (depth index, colour index) in depth order.
std::vector<std::pair<size_t, size_t>> AssociateByTime(const std::vector<TimedFile>& depth,
                                                       const std::vector<TimedFile>& color,
                                                       int64_t tolerance_ns) {
  struct Candidate {
    int64_t difference;
    size_t depth;
    size_t color;
  };
  std::vector<Candidate> candidates;
  size_t window_start = 0;
  for (size_t d = 0; d < depth.size(); ++d) {
    while (window_start < color.size() && color[window_start].ns < depth[d].ns - tolerance_ns) {
      ++window_start;
    }
    for (size_t c = window_start; c < color.size() && color[c].ns <= depth[d].ns + tolerance_ns;
         ++c) {
      candidates.push_back({std::abs(color[c].ns - depth[d].ns), d, c});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.difference, a.depth, a.color) < std::tie(b.difference, b.depth, b.color);
  });
  std::vector<bool> depth_used(depth.size(), false);
  std::vector<bool> color_used(color.size(), false);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (const Candidate& candidate : candidates) {
    if (depth_used[candidate.depth] || color_used[candidate.color]) continue;
    depth_used[candidate.depth] = true;
    color_used[candidate.color] = true;
    pairs.emplace_back(candidate.depth, candidate.color);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

// ------------------------------------------------------------------------------------------------
// Images

// A PNG or JPEG header from the file's first 64 KiB (room for EXIF segments before a JPEG's
// frame header), without decoding pixels; nullopt for other files.
std::optional<ImageHeader> ReadImageFileHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<uint8_t> bytes(64 * 1024);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return ReadImageHeader(bytes.data(), static_cast<size_t>(in.gcount()));
}

cv::Mat ReadImage(const std::string& path, const char* what) {
  cv::Mat image;
  try {
    image = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    SIGHTMAP_THROW(Error, "cannot decode the " << what << " image " << path << " (" << e.what()
                                               << "); replace the file or remove the frame");
  }
  SIGHTMAP_CHECK(!image.empty(), "cannot read the "
                                     << what << " image " << path
                                     << "; check that it exists and is a valid image file");
  return image;
}

// Falls back to decoding the image for formats other than PNG and JPEG.
ImageHeader ReadFrameImageHeader(const std::string& path, const char* what) {
  if (std::optional<ImageHeader> header = ReadImageFileHeader(path)) return *header;
  const cv::Mat image = ReadImage(path, what);
  ImageHeader header;
  header.width = image.cols;
  header.height = image.rows;
  header.bits = static_cast<int>(8 * image.elemSize1());
  header.channels = image.channels();
  return header;
}

std::string DescribeFormat(int bits, int channels) {
  return StrCat(bits, "-bit with ", channels, channels == 1 ? " channel" : " channels");
}

void CheckDepthFormat(const std::string& path, int bits, int channels) {
  SIGHTMAP_CHECK(bits == 16 && channels == 1,
                 "depth image " << path << " is " << DescribeFormat(bits, channels)
                                << ", but depth must be a single-channel 16-bit PNG; re-export it"
                                   " without converting it to 8-bit or colour");
}

// 8-bit BGR whatever the file stores (grey, BGR, BGRA).
cv::Mat LoadColor(const std::string& path) {
  cv::Mat image = ReadImage(path, "colour");
  SIGHTMAP_CHECK(
      image.depth() == CV_8U,
      "colour image " << path << " is "
                      << DescribeFormat(static_cast<int>(8 * image.elemSize1()), image.channels())
                      << ", but colour must be 8-bit; convert it to 8-bit");
  switch (image.channels()) {
    case 3:
      return image;
    case 1:
      cv::cvtColor(image, image, cv::COLOR_GRAY2BGR);
      return image;
    case 4:
      cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
      return image;
    default:
      SIGHTMAP_THROW(Error, "colour image " << path << " has " << image.channels()
                                            << " channels; save it as grey, RGB or RGBA");
  }
}

cv::Mat LoadDepth(const std::string& path) {
  cv::Mat image = ReadImage(path, "depth");
  CheckDepthFormat(path, static_cast<int>(8 * image.elemSize1()), image.channels());
  return image;
}

// ------------------------------------------------------------------------------------------------
// The source

class FolderSource : public RgbdSource {
 public:
  FolderSource(SourceMetadata metadata, std::vector<FolderFrame> frames, DepthEncoding encoding,
               int64_t unpaired_frames, bool realtime)
      : metadata_(std::move(metadata)),
        frames_(std::move(frames)),
        encoding_(encoding),
        realtime_(realtime) {
    stats_.unpaired_frames = unpaired_frames;
  }

  const SourceMetadata& metadata() const override { return metadata_; }
  SourceStats stats() const override { return stats_; }

  std::optional<RgbdFrame> Next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    const FolderFrame& entry = frames_[next_];
    RgbdFrame frame;
    frame.index = static_cast<int64_t>(next_);
    frame.timestamp_ns = entry.timestamp_ns;
    frame.color = LoadColor(entry.color_path);
    ++stats_.color_frames;
    cv::Mat depth = LoadDepth(entry.depth_path);
    ++stats_.depth_frames;
    SIGHTMAP_CHECK(depth.size() == frame.color.size(),
                   "frame " << next_ << ": depth image " << entry.depth_path << " is " << depth.cols
                            << "x" << depth.rows << " but colour image " << entry.color_path
                            << " is " << frame.color.cols << "x" << frame.color.rows
                            << "; a folder source needs depth registered at the colour size");
    SIGHTMAP_CHECK(
        frame.color.cols == metadata_.color_width && frame.color.rows == metadata_.color_height,
        "frame " << next_ << " (" << entry.color_path << ") is " << frame.color.cols << "x"
                 << frame.color.rows << " but the stream started at " << metadata_.color_width
                 << "x" << metadata_.color_height
                 << "; the intrinsics hold for one size, so split the folder by size");
    frame.depth = ToMillimetres(std::move(depth));
    frame.world_from_cam_gt = entry.world_from_cam;
    ++next_;
    ++stats_.paired_frames;
    if (realtime_) WaitForRecordedPace(frame.timestamp_ns);
    return frame;
  }

 private:
  cv::Mat ToMillimetres(cv::Mat depth) const {
    switch (encoding_) {
      case DepthEncoding::kTum5000PerMetre: {
        // v / 5 never ends in .5, so OpenCV's rounding matches round(v / 5.0); 0 stays 0.
        cv::Mat millimetres;
        depth.convertTo(millimetres, CV_16U, 1.0 / kTumDepthUnitsPerMm);
        return millimetres;
      }
      case DepthEncoding::kMillimetres:
        depth.setTo(0, depth == kSevenScenesNoDepth);
        return depth;
    }
    return depth;
  }

  void WaitForRecordedPace(TimestampNs timestamp_ns) {
    const auto now = std::chrono::steady_clock::now();
    if (!pace_start_) {
      pace_start_ = now;
      pace_first_ns_ = timestamp_ns;
      return;
    }
    std::this_thread::sleep_until(*pace_start_ +
                                  std::chrono::nanoseconds(timestamp_ns - pace_first_ns_));
  }

  SourceMetadata metadata_;
  std::vector<FolderFrame> frames_;
  DepthEncoding encoding_;
  bool realtime_;
  SourceStats stats_;
  size_t next_ = 0;
  std::optional<std::chrono::steady_clock::time_point> pace_start_;
  TimestampNs pace_first_ns_ = 0;
};

// ------------------------------------------------------------------------------------------------
// Shared set-up

void RequireFolder(const std::string& dir, const char* format, const char* hint) {
  std::error_code ec;
  SIGHTMAP_CHECK(!dir.empty() && fs::is_directory(dir, ec),
                 format << " folder " << dir << " does not exist or is not a folder; " << hint);
}

// Native sizes from the first frame's headers, which must agree (the depth is registered).
void SetSizesFromFirstFrame(const FolderFrame& first, SourceMetadata* metadata) {
  const ImageHeader color = ReadFrameImageHeader(first.color_path, "colour");
  const ImageHeader depth = ReadFrameImageHeader(first.depth_path, "depth");
  CheckDepthFormat(first.depth_path, depth.bits, depth.channels);
  SIGHTMAP_CHECK(color.width == depth.width && color.height == depth.height,
                 "the first frame's depth image "
                     << first.depth_path << " is " << depth.width << "x" << depth.height
                     << " but its colour image " << first.color_path << " is " << color.width << "x"
                     << color.height
                     << "; a folder source needs depth registered at "
                        "the colour size");
  metadata->color_width = metadata->depth_width = color.width;
  metadata->color_height = metadata->depth_height = color.height;
}

// What every folder source states about itself: registered depth, one frame per listed pair.
SourceMetadata FolderMetadata(const char* kind, const std::string& dir, const char* device_name,
                              const std::vector<FolderFrame>& frames,
                              size_t frames_without_ground_truth) {
  SourceMetadata metadata;
  metadata.kind = kind;
  metadata.uri = dir;
  metadata.device_name = device_name;
  metadata.registration = DepthRegistration::kSource;
  SetSizesFromFirstFrame(frames.front(), &metadata);
  metadata.depth_frame_count = static_cast<int64_t>(frames.size());
  metadata.color_frame_count = static_cast<int64_t>(frames.size());
  metadata.has_ground_truth = frames_without_ground_truth < frames.size();
  return metadata;
}

// The colour intrinsics of options.calibration_file, when it has them, replace the folder's.
// Returns whether they did.
bool ApplyCalibrationFile(const SourceOptions& options, SourceMetadata* metadata) {
  if (options.calibration_file.empty()) return false;
  const std::string& file = options.calibration_file;
  const RgbdCalibration calibration = ReadCalibrationFile(file);
  if (calibration.depth || calibration.color_from_depth) {
    metadata->notes.push_back(StrCat("The depth intrinsics and color_from_depth in ", file,
                                     " are ignored: the folder's depth is already registered to"
                                     " colour."));
  }
  if (!calibration.color) {
    metadata->notes.push_back(
        StrCat(file, " has no \"color\" block, so the folder's intrinsics are kept."));
    return false;
  }
  Intrinsics k = *calibration.color;
  const int width = metadata->color_width;
  const int height = metadata->color_height;
  std::string scaled;
  if (k.width > 0 && k.height > 0 && (k.width != width || k.height != height)) {
    scaled = StrCat(", scaled from ", k.width, "x", k.height);
    k = k.Scaled(width, height);
  }
  k.width = width;
  k.height = height;
  std::string error;
  SIGHTMAP_CHECK(k.Check(&error), file << " gives unusable colour intrinsics (" << error
                                       << "); fix its \"color\" block");
  metadata->intrinsics = k;
  metadata->intrinsics_origin = "calibration-file";
  metadata->notes.push_back(
      StrCat("Colour intrinsics ", FormatIntrinsics(k), " from ", file, scaled, "."));
  return true;
}

std::string GroundTruthCountNote(size_t without, size_t total, const std::string& reason) {
  if (without == 0) return "";
  return StrCat(" ", without, " of ", total, " frames ", reason, " and carry none.");
}

// ------------------------------------------------------------------------------------------------
// 3DMatch folder scan

struct ThreeDMatchFiles {
  std::string color;
  std::string depth;
  std::string pose;
};

// frame-<digits>.<suffix> files of one folder, by frame number.
std::map<int64_t, ThreeDMatchFiles> ScanThreeDMatchFrames(const fs::path& dir) {
  std::map<int64_t, ThreeDMatchFiles> frames;
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir, ec)) {
    if (!entry.is_regular_file(ec)) continue;
    const std::string name = entry.path().filename().string();
    constexpr const char* kPrefix = "frame-";
    if (name.rfind(kPrefix, 0) != 0) continue;
    const size_t digits_begin = std::strlen(kPrefix);
    const size_t digits_end = name.find('.', digits_begin);
    if (digits_end == std::string::npos || digits_end == digits_begin ||
        digits_end - digits_begin > 12) {
      continue;
    }
    const std::string digits = name.substr(digits_begin, digits_end - digits_begin);
    if (!AllDigits(digits)) continue;
    const std::string suffix = name.substr(digits_end);
    ThreeDMatchFiles& files = frames[std::stoll(digits)];
    const std::string path = entry.path().string();
    if (suffix == ".color.png") {
      files.color = path;  // preferred over a JPEG copy
    } else if (suffix == ".color.jpg" && files.color.empty()) {
      files.color = path;
    } else if (suffix == ".depth.png") {
      files.depth = path;
    } else if (suffix == ".pose.txt") {
      files.pose = path;
    }
  }
  for (auto it = frames.begin(); it != frames.end();) {
    it = it->second.color.empty() && it->second.depth.empty() ? frames.erase(it) : std::next(it);
  }
  return frames;
}

std::vector<double> ReadNumbers(const fs::path& path) {
  std::ifstream in = OpenInputFile(path.string(), "numbers file");
  SIGHTMAP_CHECK(in, "cannot read " << path.string() << "; check that the file is readable");
  std::vector<double> numbers;
  std::string token;
  while (in >> token) {
    double value = 0.0;
    SIGHTMAP_CHECK(ParseNumberOrInfinity(token, &value),
                   path.string() << ": \"" << token << "\" is not a number; fix the file");
    numbers.push_back(value);
  }
  return numbers;
}

// nullopt when the file holds non-finite values, which 3DMatch uses to mark frames without a pose.
std::optional<Eigen::Isometry3d> ReadThreeDMatchPose(const fs::path& path) {
  const std::vector<double> v = ReadNumbers(path);
  SIGHTMAP_CHECK(v.size() == 16, path.string() << ": expected 16 numbers (a 4x4 camera-to-world "
                                                  "matrix) but found "
                                               << v.size() << "; fix or delete the file");
  if (!std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); })) {
    return std::nullopt;
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<size_t>(4 * r + c)];
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  const bool rigid =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <
          1e-3 &&
      rotation.determinant() > 0.0 &&
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() < 1e-6;
  SIGHTMAP_CHECK(rigid, path.string() << " is not a rigid transform (rotation not orthonormal or"
                                         " last row not 0 0 0 1); fix or delete the file");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  // The files keep ~7 digits; re-orthonormalise so inverses stay exact downstream.
  pose.linear() = Eigen::Quaterniond(rotation).normalized().toRotationMatrix();
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

Intrinsics ReadCameraIntrinsicsTxt(const fs::path& path, int width, int height,
                                   std::vector<std::string>* notes) {
  const std::vector<double> k = ReadNumbers(path);
  SIGHTMAP_CHECK(k.size() == 9 && k[0] > 0.0 && k[4] > 0.0 && std::abs(k[3]) < 1e-9 &&
                     std::abs(k[6]) < 1e-9 && std::abs(k[7]) < 1e-9 && std::abs(k[8] - 1.0) < 1e-9,
                 path.string() << " is not a 3x3 camera matrix \"fx 0 cx  0 fy cy  0 0 1\"; fix"
                                  " the file");
  if (std::abs(k[1]) > 1e-9) {
    notes->push_back(StrCat(path.string(), " has a skew of ", k[1], ", which is ignored."));
  }
  return Intrinsics::FromPinhole(width, height, k[0], k[4], k[2], k[5]);
}

}  // namespace

// ------------------------------------------------------------------------------------------------

namespace {

// The listed frames of a TUM folder, paired depth to colour, with their ground truth.
struct TumFrames {
  std::vector<FolderFrame> frames;
  size_t without_ground_truth = 0;
};

TumFrames ReadTumFrames(const fs::path& root, const std::vector<TimedFile>& colors,
                        const std::vector<TimedFile>& depths,
                        const std::vector<std::pair<size_t, size_t>>& pairs,
                        const std::vector<GroundTruthSample>& ground_truth) {
  TumFrames read;
  read.frames.reserve(pairs.size());
  for (const auto& [d, c] : pairs) {
    FolderFrame frame;
    frame.color_path = (root / colors[c].file).string();
    frame.depth_path = (root / depths[d].file).string();
    SIGHTMAP_CHECK(fs::is_regular_file(frame.color_path),
                   (root / "rgb.txt").string()
                       << ":" << colors[c].line << " names " << colors[c].file
                       << ", which does not exist; restore the image or"
                          " delete the line");
    SIGHTMAP_CHECK(fs::is_regular_file(frame.depth_path),
                   (root / "depth.txt").string()
                       << ":" << depths[d].line << " names " << depths[d].file
                       << ", which does not exist; restore the image or"
                          " delete the line");
    frame.timestamp_ns = depths[d].ns;
    frame.world_from_cam = InterpolateGroundTruth(ground_truth, frame.timestamp_ns);
    if (!frame.world_from_cam) ++read.without_ground_truth;
    read.frames.push_back(std::move(frame));
  }
  return read;
}

// The nominal rate from the median interval between depth.txt's timestamps (0 with fewer than
// two rising ones) [Hz].
double TumNominalFps(const std::vector<TimedFile>& depths) {
  std::vector<int64_t> intervals;
  for (size_t i = 1; i < depths.size(); ++i) {
    if (depths[i].ns > depths[i - 1].ns) intervals.push_back(depths[i].ns - depths[i - 1].ns);
  }
  if (intervals.empty()) return 0.0;
  std::nth_element(intervals.begin(), intervals.begin() + intervals.size() / 2, intervals.end());
  return 1e9 / static_cast<double>(intervals[intervals.size() / 2]);
}

// TUM folders carry no intrinsics: --calib, else the TUM ROS default scaled to the images.
void ApplyTumIntrinsics(const SourceOptions& options, SourceMetadata* metadata) {
  const Intrinsics tum_default = {640, 480, 525.0, 525.0, 319.5, 239.5};
  metadata->intrinsics = tum_default;
  metadata->intrinsics_origin = "default (TUM ROS)";
  if (ApplyCalibrationFile(options, metadata)) return;
  std::string scaled;
  if (metadata->color_width != tum_default.width || metadata->color_height != tum_default.height) {
    metadata->intrinsics = tum_default.Scaled(metadata->color_width, metadata->color_height);
    scaled = StrCat(", scaled to ", FormatIntrinsics(metadata->intrinsics));
  }
  metadata->notes.push_back(
      StrCat("TUM folders carry no intrinsics: using the TUM ROS default ",
             FormatIntrinsics(tum_default), scaled,
             "; the freiburg1/2/3 cameras differ from it, so pass --calib FILE with the sequence's "
             "camera to override."));
}

}  // namespace

std::unique_ptr<RgbdSource> OpenTumFolder(const std::string& dir, const SourceOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  RequireFolder(dir, "TUM RGB-D",
                "pass tum:DIR with the folder that holds rgb.txt, depth.txt and the images");
  const fs::path root(dir);
  for (const char* list : {"rgb.txt", "depth.txt"}) {
    SIGHTMAP_CHECK(fs::is_regular_file(root / list),
                   "TUM folder " << dir << " has no " << list
                                 << "; a TUM RGB-D folder lists its images in rgb.txt and depth.txt"
                                    ", so check the path (3DMatch folders take 3dmatch:DIR)");
  }
  const std::vector<TimedFile> colors = ReadTumFileList(root / "rgb.txt");
  const std::vector<TimedFile> depths = ReadTumFileList(root / "depth.txt");
  SIGHTMAP_CHECK(!colors.empty() && !depths.empty(),
                 "TUM folder " << dir << " lists " << colors.size() << " colour and "
                               << depths.size()
                               << " depth frames; rgb.txt and depth.txt must both list frames");
  const std::vector<std::pair<size_t, size_t>> pairs =
      AssociateByTime(depths, colors, options.sync_tolerance_ns);
  SIGHTMAP_CHECK(!pairs.empty(), "none of the " << depths.size() << " depth frames in " << dir
                                                << " has a colour frame within "
                                                << FormatMs(options.sync_tolerance_ns)
                                                << "; check that rgb.txt and depth.txt belong to"
                                                   " one recording, or raise the sync tolerance");
  const fs::path ground_truth_file = root / "groundtruth.txt";
  const bool has_ground_truth_file = fs::is_regular_file(ground_truth_file);
  TumFrames read = ReadTumFrames(root, colors, depths, pairs,
                                 has_ground_truth_file ? ReadTumGroundTruth(ground_truth_file)
                                                       : std::vector<GroundTruthSample>());

  SourceMetadata metadata =
      FolderMetadata("tum", dir, "TUM RGB-D folder", read.frames, read.without_ground_truth);
  std::vector<std::string>& notes = metadata.notes;
  notes.push_back(
      "Depth PNGs hold 5000 units per metre (TUM convention); values are divided by 5 and rounded"
      " to millimetres, 0 stays \"no measurement\".");
  notes.push_back(
      "Depth is taken as registered to colour: the TUM RGB-D sequences were recorded with the "
      "Kinect's registration on.");
  const size_t unpaired_depth = depths.size() - pairs.size();
  const size_t unpaired_color = colors.size() - pairs.size();
  notes.push_back(StrCat("Each depth frame was paired with the nearest colour frame within ",
                         FormatMs(options.sync_tolerance_ns),
                         ", each colour frame used once (as TUM's associate.py): ", pairs.size(),
                         " pairs; ", unpaired_depth, " depth and ", unpaired_color,
                         " colour frames had no partner and are skipped."));
  notes.push_back(
      "Timestamps are the depth times from depth.txt, in nanoseconds since the Unix epoch.");
  if (const double fps = TumNominalFps(depths); fps > 0.0) {
    metadata.nominal_fps = fps;
    notes.push_back(StrCat("Nominal rate ", metadata.nominal_fps,
                           " Hz from the median interval between depth.txt timestamps."));
  }
  if (has_ground_truth_file) {
    notes.push_back(
        StrCat("Ground truth: world_from_cam from groundtruth.txt, interpolated at each depth time "
               "(linear translation, slerp rotation) between poses at most ",
               FormatMs(kMaxGroundTruthGapNs), " apart.",
               GroundTruthCountNote(read.without_ground_truth, read.frames.size(),
                                    "fall outside groundtruth.txt or in a gap")));
  } else {
    notes.push_back("No groundtruth.txt: frames carry no ground truth.");
  }
  ApplyTumIntrinsics(options, &metadata);

  return std::make_unique<FolderSource>(
      std::move(metadata), std::move(read.frames), DepthEncoding::kTum5000PerMetre,
      static_cast<int64_t>(unpaired_depth + unpaired_color), options.realtime);
}

namespace {

// A 3DMatch sequence: the folder that holds its frames and their files by number.
struct ThreeDMatchSequence {
  fs::path dir;
  std::map<int64_t, ThreeDMatchFiles> files;
};

// `dir` itself, or its one seq-* subfolder (a scene folder); notes which. Throws when it holds
// none, or several to choose from.
ThreeDMatchSequence FindThreeDMatchSequence(const std::string& dir,
                                            std::vector<std::string>* notes) {
  fs::path frames_dir = fs::absolute(fs::path(dir)).lexically_normal();
  if (!frames_dir.has_filename()) frames_dir = frames_dir.parent_path();
  std::map<int64_t, ThreeDMatchFiles> files = ScanThreeDMatchFrames(frames_dir);
  if (!files.empty()) return {frames_dir, std::move(files)};
  // Each seq-* subfolder with frames, scanned once.
  std::vector<ThreeDMatchSequence> sequences;
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(frames_dir, ec)) {
    if (!entry.is_directory(ec) || entry.path().filename().string().rfind("seq-", 0) != 0) {
      continue;
    }
    std::map<int64_t, ThreeDMatchFiles> sequence_files = ScanThreeDMatchFrames(entry.path());
    if (!sequence_files.empty()) sequences.push_back({entry.path(), std::move(sequence_files)});
  }
  std::sort(
      sequences.begin(), sequences.end(),
      [](const ThreeDMatchSequence& a, const ThreeDMatchSequence& b) { return a.dir < b.dir; });
  SIGHTMAP_CHECK(!sequences.empty(),
                 "3DMatch folder " << dir
                                   << " holds no frame-NNNNNN.color.png / frame-NNNNNN.depth.png"
                                      " images, nor a seq-* folder with them; check the path");
  if (sequences.size() > 1) {
    std::ostringstream names;
    for (size_t i = 0; i < sequences.size(); ++i) {
      names << (i ? ", " : "") << sequences[i].dir.filename().string();
    }
    SIGHTMAP_THROW(Error, "3DMatch folder "
                              << dir << " holds " << sequences.size() << " sequences ("
                              << names.str() << "); pass one of them, e.g. 3dmatch:"
                              << (fs::path(dir) / sequences.front().dir.filename()).string());
  }
  notes->push_back(StrCat(dir, " holds one sequence, ", sequences.front().dir.filename().string(),
                          "; reading it."));
  return std::move(sequences.front());
}

// A sequence's frames with both images, in number order, stamped N / 30 s, with their poses.
struct ThreeDMatchFrames {
  std::vector<FolderFrame> frames;
  std::vector<int64_t> numbers;         // each frame's N
  std::vector<std::string> incomplete;  // an image of each frame that lacks its other one
  size_t without_pose_file = 0;
  size_t invalid_pose = 0;  // pose.txt with non-finite values
};

ThreeDMatchFrames ReadThreeDMatchFrames(const ThreeDMatchSequence& sequence) {
  ThreeDMatchFrames read;
  for (const auto& [number, frame_files] : sequence.files) {
    if (frame_files.color.empty() || frame_files.depth.empty()) {
      read.incomplete.push_back(frame_files.color.empty() ? frame_files.depth : frame_files.color);
      continue;
    }
    FolderFrame frame;
    frame.color_path = frame_files.color;
    frame.depth_path = frame_files.depth;
    frame.timestamp_ns = number * kThreeDMatchFramePeriodNs;
    if (frame_files.pose.empty()) {
      ++read.without_pose_file;
    } else {
      frame.world_from_cam = ReadThreeDMatchPose(frame_files.pose);
      if (!frame.world_from_cam) ++read.invalid_pose;
    }
    read.frames.push_back(std::move(frame));
    read.numbers.push_back(number);
  }
  SIGHTMAP_CHECK(!read.frames.empty(), "3DMatch folder "
                                           << sequence.dir.string()
                                           << " has no frame with both frame-N.color.png and"
                                              " frame-N.depth.png; check the path");
  return read;
}

// The colour intrinsics from camera-intrinsics.txt in the sequence's folder or its parent (the
// scene's), or from --calib; throws without either.
void ApplyThreeDMatchIntrinsics(const fs::path& frames_dir, const SourceOptions& options,
                                SourceMetadata* metadata) {
  fs::path intrinsics_file;
  for (const fs::path& candidate :
       {frames_dir / "camera-intrinsics.txt", frames_dir.parent_path() / "camera-intrinsics.txt"}) {
    if (fs::is_regular_file(candidate)) {
      intrinsics_file = candidate;
      break;
    }
  }
  if (!intrinsics_file.empty()) {
    metadata->intrinsics = ReadCameraIntrinsicsTxt(intrinsics_file, metadata->color_width,
                                                   metadata->color_height, &metadata->notes);
    metadata->intrinsics_origin = "camera-intrinsics.txt";
    metadata->notes.push_back(StrCat("Colour intrinsics ", FormatIntrinsics(metadata->intrinsics),
                                     " from ", intrinsics_file.string(),
                                     "; the file gives no image size, so it is taken to be the "
                                     "images'."));
  }
  const bool calibrated = ApplyCalibrationFile(options, metadata);
  SIGHTMAP_CHECK(calibrated || !intrinsics_file.empty(),
                 "3DMatch folder " << frames_dir.string()
                                   << " has no camera-intrinsics.txt, in it or its parent; put the"
                                      " 3x3 camera matrix there (7-Scenes' Kinect is usually given"
                                      " fx = fy = 585, cx = 320, cy = 240) or pass --calib FILE");
}

// What the source says of its depth, timestamps, skipped frames and ground truth.
void AddThreeDMatchNotes(const ThreeDMatchFrames& read, std::vector<std::string>* notes) {
  notes->push_back(
      "Depth PNGs are millimetres as stored; 65535 (7-Scenes' marker for no measurement) becomes"
      " 0. Depth is taken as registered to colour.");
  std::string gaps;
  const std::vector<int64_t>& numbers = read.numbers;
  if (numbers.back() - numbers.front() + 1 != static_cast<int64_t>(numbers.size())) {
    gaps = StrCat(" Frame numbers have gaps (", numbers.size(), " frames numbered ",
                  numbers.front(), " to ", numbers.back(), "), so the timestamps do too.");
  }
  notes->push_back(StrCat(
      "3DMatch folders have no timestamps: frame N is stamped N / 30 s (30 Hz nominal).", gaps));
  if (!read.incomplete.empty()) {
    notes->push_back(StrCat(read.incomplete.size(),
                            " frames lack their colour or depth image and are skipped"
                            " (first: ",
                            read.incomplete.front(), ")."));
  }
  const size_t without_ground_truth = read.without_pose_file + read.invalid_pose;
  if (without_ground_truth == 0) {
    notes->push_back("Ground truth: world_from_cam from each frame's pose.txt.");
  } else if (without_ground_truth == read.frames.size() && read.invalid_pose == 0) {
    notes->push_back("No frame-N.pose.txt files: frames carry no ground truth.");
  } else {
    notes->push_back(
        StrCat("Ground truth: world_from_cam from each frame's pose.txt.",
               GroundTruthCountNote(read.without_pose_file, read.frames.size(), "have no pose.txt"),
               GroundTruthCountNote(read.invalid_pose, read.frames.size(),
                                    "have a pose.txt with non-finite values (no pose)")));
  }
}

}  // namespace

std::unique_ptr<RgbdSource> OpenThreeDMatchFolder(const std::string& dir,
                                                  const SourceOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  RequireFolder(dir, "3DMatch", "pass 3dmatch:DIR with the folder of frame-NNNNNN.* files");
  std::vector<std::string> notes;
  const ThreeDMatchSequence sequence = FindThreeDMatchSequence(dir, &notes);
  ThreeDMatchFrames read = ReadThreeDMatchFrames(sequence);
  SourceMetadata metadata = FolderMetadata("3dmatch", dir, "3DMatch folder", read.frames,
                                           read.without_pose_file + read.invalid_pose);
  metadata.nominal_fps = kThreeDMatchNominalFps;
  metadata.notes = std::move(notes);
  ApplyThreeDMatchIntrinsics(sequence.dir, options, &metadata);
  AddThreeDMatchNotes(read, &metadata.notes);
  const auto skipped = static_cast<int64_t>(read.incomplete.size());
  return std::make_unique<FolderSource>(std::move(metadata), std::move(read.frames),
                                        DepthEncoding::kMillimetres, skipped, options.realtime);
}

namespace {

void WritePngAtomically(const std::string& path, const cv::Mat& image) {
  std::vector<uchar> bytes;
  SIGHTMAP_CHECK(cv::imencode(".png", image, bytes), "cannot encode " << path << " as PNG");
  WriteFileAtomically(path,
                      std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

void WriteThreeDMatchFrame(const std::string& dir, const RgbdFrame& frame) {
  char stem[32];
  std::snprintf(stem, sizeof(stem), "frame-%06lld", static_cast<long long>(frame.index));
  const std::string base = (fs::path(dir) / stem).string();
  WritePngAtomically(base + ".color.png", frame.color);
  WritePngAtomically(base + ".depth.png", frame.depth);
  if (frame.world_from_cam_gt) {
    std::ostringstream pose;
    pose << std::setprecision(17) << frame.world_from_cam_gt->matrix() << "\n";
    WriteFileAtomically(base + ".pose.txt", pose.str());
  }
}

void WriteThreeDMatchIntrinsics(const std::string& dir, const Intrinsics& k) {
  std::ostringstream text;
  text << std::setprecision(17) << k.fx << " 0 " << k.cx << "\n0 " << k.fy << " " << k.cy
       << "\n0 0 1\n";
  WriteFileAtomically((fs::path(dir) / "camera-intrinsics.txt").string(), text.str());
}

}  // namespace sightmap::capture
