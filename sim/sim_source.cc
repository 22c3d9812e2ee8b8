#include "sim/sim_source.h"

#include <algorithm>
#include <charconv>
#include <limits>
#include <sstream>
#include <string>

#include "core/check.h"

namespace sightmap::sim {
namespace {

class SimSource : public capture::RgbdSource {
 public:
  explicit SimSource(const SimulatorOptions& options) : simulator_(options) {
    const Intrinsics& k = simulator_.options().camera;
    metadata_.kind = "sim";
    metadata_.uri = "sim:" + options.scene;
    metadata_.device_name = "sightmap synthetic building (" + simulator_.scene().name + ")";
    metadata_.vendor = "sightmap";
    metadata_.color_width = metadata_.depth_width = k.width;
    metadata_.color_height = metadata_.depth_height = k.height;
    metadata_.intrinsics = k;
    metadata_.intrinsics_origin = "simulator";
    metadata_.registration = capture::DepthRegistration::kSource;
    metadata_.nominal_fps = options.fps;
    metadata_.depth_frame_count = simulator_.num_frames();
    metadata_.color_frame_count = simulator_.num_frames();
    metadata_.has_ground_truth = true;
    std::ostringstream note;
    note << "synthetic " << ToString(options.trajectory) << " walk, session " << options.session
         << ", seed " << options.seed << ", " << simulator_.num_frames() << " frames at "
         << options.fps << " Hz; Kinect v1 depth noise model; ground-truth poses";
    metadata_.notes.push_back(note.str());
  }

  const capture::SourceMetadata& metadata() const override { return metadata_; }

  std::optional<RgbdFrame> Next() override {
    if (next_ >= simulator_.num_frames()) return std::nullopt;
    RgbdFrame frame = simulator_.RenderFrame(next_++);
    ++stats_.depth_frames;
    ++stats_.color_frames;
    ++stats_.paired_frames;
    return frame;
  }

  std::optional<FrameStamp> PeekStamp() const override {
    if (next_ >= simulator_.num_frames()) return std::nullopt;
    return FrameStamp{next_, simulator_.TimestampOf(next_)};
  }

  void SkipNext() override { ++next_; }

  capture::SourceStats stats() const override { return stats_; }

 private:
  Simulator simulator_;
  capture::SourceMetadata metadata_;
  capture::SourceStats stats_;
  int64_t next_ = 0;
};

constexpr const char* kAccepted =
    " — accepted: sim:NAME?trajectory=handheld|robot|survey&session=N&seed=N&fps=F&frames=N";

[[noreturn]] void ThrowBadOption(const std::string& key, const std::string& value,
                                 const std::string& wanted) {
  SIGHTMAP_THROW(InvalidArgument,
                 "sim: option " << key << "=" << value << " must be " << wanted << kAccepted);
}

// A whole number from `min` to `max`, digits only: ">>" would read "1.5" as 1 and "-3" into an
// unsigned seed as 2^64 - 3, and -1 (the default's marker for frames) is no count a user means.
uint64_t ParseWhole(const std::string& key, const std::string& value, uint64_t min, uint64_t max) {
  const std::string wanted =
      "a whole number from " + std::to_string(min) + " to " + std::to_string(max);
  uint64_t number = 0;
  const char* end = value.data() + value.size();
  const bool digits = !value.empty() && std::all_of(value.begin(), value.end(),
                                                    [](char c) { return c >= '0' && c <= '9'; });
  if (!digits || std::from_chars(value.data(), end, number).ptr != end || number < min ||
      number > max) {
    ThrowBadOption(key, value, wanted);
  }
  return number;
}

double ParseFps(const std::string& key, const std::string& value) {
  std::istringstream in(value);
  double number = 0.0;
  in >> number;
  if (!in || !in.eof() || !(number > 0.0 && number <= 120.0)) {
    ThrowBadOption(key, value, "a number above 0 and at most 120 Hz");
  }
  return number;
}

}  // namespace

SimulatorOptions ParseSimLocation(const std::string& location) {
  SimulatorOptions options;
  const size_t question = location.find('?');
  options.scene = location.substr(0, question);
  if (options.scene.empty()) options.scene = "office";
  if (question == std::string::npos) return options;
  std::istringstream query(location.substr(question + 1));
  std::string pair;
  while (std::getline(query, pair, '&')) {
    if (pair.empty()) continue;
    const size_t eq = pair.find('=');
    if (eq == std::string::npos) {
      SIGHTMAP_THROW(InvalidArgument, "sim: option '" << pair << "' lacks '='" << kAccepted);
    }
    const std::string key = pair.substr(0, eq);
    const std::string value = pair.substr(eq + 1);
    if (key == "trajectory") {
      options.trajectory = ParseTrajectoryKind(value);
    } else if (key == "session") {
      options.session = static_cast<int>(ParseWhole(key, value, 1, 1000));
    } else if (key == "seed") {
      options.seed = ParseWhole(key, value, 0, std::numeric_limits<uint64_t>::max());
    } else if (key == "fps") {
      options.fps = ParseFps(key, value);
    } else if (key == "frames") {
      options.frames = static_cast<int64_t>(ParseWhole(key, value, 1, 10'000'000));
    } else {
      SIGHTMAP_THROW(InvalidArgument, "unknown sim: option '" << key << "'" << kAccepted);
    }
  }
  SIGHTMAP_CHECK_OPTIONS(options);
  return options;
}

std::unique_ptr<capture::RgbdSource> OpenSimSource(const SimulatorOptions& options) {
  return std::make_unique<SimSource>(options);
}

void RegisterSimSource() {
  capture::RegisterSourceOpener(
      capture::SourceSpec::Kind::kSim,
      [](const std::string& location, const capture::SourceOptions& /*options*/) {
        return OpenSimSource(ParseSimLocation(location));
      });
}

}  // namespace sightmap::sim
