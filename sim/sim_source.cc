#include "sim/sim_source.h"

#include <sstream>

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
    " — accepted: sim:NAME?trajectory=handheld|robot&session=N&seed=N&fps=F&frames=N";

template <typename T>
T ParseNumber(const std::string& key, const std::string& value) {
  std::istringstream in(value);
  T number{};
  in >> number;
  if (!in || !in.eof()) {
    SIGHTMAP_THROW(InvalidArgument,
                   "sim: option " << key << "=" << value << " is not a number" << kAccepted);
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
      options.session = ParseNumber<int>(key, value);
    } else if (key == "seed") {
      options.seed = ParseNumber<uint64_t>(key, value);
    } else if (key == "fps") {
      options.fps = ParseNumber<double>(key, value);
    } else if (key == "frames") {
      options.frames = ParseNumber<int64_t>(key, value);
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
