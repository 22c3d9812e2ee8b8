// Every RGB-D source (live OpenNI2 device, .oni recording, image folder, simulator) behind one
// interface, named by one SOURCE string (see OpenSource).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "core/camera.h"
#include "core/rgbd_frame.h"

namespace sightmap::capture {

struct SourceOptions {
  // Live devices: requested stream size [px] and rate [Hz]. The closest mode the device offers is
  // taken when the exact one is missing, and the metadata notes say so.
  int width = 640;
  int height = 480;
  int fps = 30;
  // Recordings: keep the recorded pace instead of reading as fast as the consumer reads.
  bool realtime = false;
  // A colour and a depth frame further apart than this are not paired [ns].
  int64_t sync_tolerance_ns = 20'000'000;
  // Live devices: no frame for this long ends the stream with an error (sensor unplugged) [ms].
  // Recordings: the longest wait for a frame the file header promised (truncated files) [ms].
  int frame_timeout_ms = 2000;
  // Optional JSON calibration (see capture/calibration.h): replaces the intrinsics derived from the
  // field of view and the sensor family's default depth-to-colour transform.
  std::string calibration_file;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const SourceOptions& options);
void from_json(const nlohmann::json& json, SourceOptions& options);

// How the depth image came to be registered to the colour image.
enum class DepthRegistration {
  kDevice,    // the sensor registered depth to colour in hardware
  kSoftware,  // sightmap re-projected depth into the colour camera (see metadata notes)
  kSource,    // the source delivers registered depth (image folders, simulator)
  kNone,      // not registered: depth and colour come from different viewpoints
};
const char* ToString(DepthRegistration registration);

struct SourceMetadata {
  std::string kind;  // "openni", "oni", "tum", "3dmatch", "sim"
  std::string uri;   // the device URI, file or folder path
  std::string device_name;
  std::string vendor;
  std::string serial;  // empty when unknown

  // Native stream sizes [px] as the source delivers them, before any mapping.
  int color_width = 0;
  int color_height = 0;
  int depth_width = 0;
  int depth_height = 0;

  // The camera of the frames Next() returns: the colour camera, at the colour image size.
  Intrinsics intrinsics;
  std::string
      intrinsics_origin;  // "field-of-view", "calibration-file", "camera-intrinsics.txt", ...

  DepthRegistration registration = DepthRegistration::kNone;
  bool depth_resized_to_color = false;  // depth and colour differed in size; depth was mapped
  bool mirrored_in_software = false;    // the recording was mirrored; frames were flipped back

  double nominal_fps = 0.0;  // [Hz], 0 when unknown
  // Frames the source will deliver per stream, when known in advance (recordings, folders).
  std::optional<int64_t> depth_frame_count;
  std::optional<int64_t> color_frame_count;
  bool has_ground_truth = false;

  // Human-readable remarks on every conversion the source applies, for `probe` and the model.
  std::vector<std::string> notes;
};

// What a source has read so far, per stream.
struct SourceStats {
  int64_t depth_frames = 0;
  int64_t color_frames = 0;
  int64_t paired_frames = 0;    // frames returned by Next()
  int64_t unpaired_frames = 0;  // depth or colour frames dropped for lack of a partner in time
  // Frames the device numbered but the reader never got: it fell behind a live sensor, or a
  // recording played at its recorded pace, and the driver kept only the newest frame.
  int64_t missed_depth_frames = 0;
  int64_t missed_color_frames = 0;
};

class RgbdSource {
 public:
  virtual ~RgbdSource() = default;
  RgbdSource() = default;
  RgbdSource(const RgbdSource&) = delete;
  RgbdSource& operator=(const RgbdSource&) = delete;

  virtual const SourceMetadata& metadata() const = 0;

  // The next registered frame (BGR colour, 16-bit mm depth of the same size), or std::nullopt at
  // the end of the stream. Throws sightmap::Error when the source fails (sensor unplugged, a
  // corrupt file); the message says what happened and what to do.
  virtual std::optional<RgbdFrame> Next() = 0;

  // The index and timestamp Next() would return, when the source knows them without producing the
  // frame (the simulator renders each frame, so skipping the first hours of a walk by Next()
  // would render them all); nullopt when it does not, or at the end. With SkipNext(), lets a
  // resumed replay pass over frames it already mapped.
  struct FrameStamp {
    int64_t index = 0;
    TimestampNs timestamp_ns = 0;
  };
  virtual std::optional<FrameStamp> PeekStamp() const { return std::nullopt; }
  // Passes over the frame PeekStamp() described; only valid after it returned one.
  virtual void SkipNext() {}

  virtual SourceStats stats() const = 0;
};

// Parsed form of a SOURCE string.
struct SourceSpec {
  enum class Kind { kOpenNi, kOniFile, kTum, kThreeDMatch, kSim };
  Kind kind = Kind::kOpenNi;
  std::string location;  // device URI (empty = first device), file path, folder or scene name
};

// SOURCE strings:
//   openni://               the first OpenNI2 device      openni://URI   that device
//   PATH.oni                an OpenNI recording
//   tum:DIR                 a TUM RGB-D folder            3dmatch:DIR    a 3DMatch / 7-Scenes
//   folder sim:NAME                the synthetic building (reserved)
// A bare folder is recognised by its layout (rgb.txt -> tum, camera-intrinsics.txt -> 3dmatch).
// Throws InvalidArgument with a message that lists the accepted forms.
SourceSpec ParseSourceSpec(const std::string& source);

// Opens the sources of a kind implemented above capture/: the synthetic building (sim/) renders
// through render/, so it registers itself at start-up (sim::RegisterSimSource()) instead of
// capture depending on it. Thread-safe; a later registration replaces an earlier one.
using SourceOpener = std::function<std::unique_ptr<RgbdSource>(const std::string& location,
                                                               const SourceOptions& options)>;
void RegisterSourceOpener(SourceSpec::Kind kind, SourceOpener opener);

// Opens any source. Throws sightmap::Error when it cannot be opened, with what to do.
std::unique_ptr<RgbdSource> OpenSource(const std::string& source,
                                       const SourceOptions& options = SourceOptions());

}  // namespace sightmap::capture
