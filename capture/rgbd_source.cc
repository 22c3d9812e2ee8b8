#include "capture/rgbd_source.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <mutex>

#include "capture/folder_source.h"
#include "capture/openni_source.h"
#include "core/check.h"
#include "core/options_json.h"

namespace sightmap::capture {
namespace {

constexpr char kSourceForms[] =
    "use openni:// (first sensor), openni://URI, FILE.oni, tum:DIR, 3dmatch:DIR or sim:NAME";

bool StartsWith(const std::string& text, const std::string& prefix) {
  return text.compare(0, prefix.size(), prefix) == 0;
}

bool EndsWithNoCase(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) return false;
  return std::equal(suffix.rbegin(), suffix.rend(), text.rbegin(), [](char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) ==
           std::tolower(static_cast<unsigned char>(b));
  });
}

std::mutex& OpenersMutex() {
  static std::mutex mutex;
  return mutex;
}

std::map<SourceSpec::Kind, SourceOpener>& Openers() {
  static std::map<SourceSpec::Kind, SourceOpener> openers;
  return openers;
}

SourceOpener FindOpener(SourceSpec::Kind kind) {
  std::lock_guard<std::mutex> lock(OpenersMutex());
  const auto it = Openers().find(kind);
  return it == Openers().end() ? SourceOpener() : it->second;
}

}  // namespace

void RegisterSourceOpener(SourceSpec::Kind kind, SourceOpener opener) {
  std::lock_guard<std::mutex> lock(OpenersMutex());
  Openers()[kind] = std::move(opener);
}

bool SourceOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (width <= 0 || height <= 0) return fail("width and height must be positive");
  if (fps <= 0 || fps > 1000) return fail("fps must be in 1..1000");
  if (sync_tolerance_ns < 0) return fail("sync_tolerance_ns must not be negative");
  if (frame_timeout_ms <= 0) return fail("frame_timeout_ms must be positive");
  return true;
}

const char* ToString(DepthRegistration registration) {
  switch (registration) {
    case DepthRegistration::kDevice:
      return "device";
    case DepthRegistration::kSoftware:
      return "software";
    case DepthRegistration::kSource:
      return "source";
    case DepthRegistration::kNone:
      return "none";
  }
  return "unknown";
}

SourceSpec ParseSourceSpec(const std::string& source) {
  SIGHTMAP_CHECK(!source.empty(), "empty SOURCE: " << kSourceForms);
  SourceSpec spec;
  auto with_location = [&](SourceSpec::Kind kind, const std::string& prefix) {
    spec.kind = kind;
    spec.location = source.substr(prefix.size());
    return spec;
  };
  if (StartsWith(source, "openni://")) return with_location(SourceSpec::Kind::kOpenNi, "openni://");
  if (StartsWith(source, "tum:")) return with_location(SourceSpec::Kind::kTum, "tum:");
  if (StartsWith(source, "3dmatch:"))
    return with_location(SourceSpec::Kind::kThreeDMatch, "3dmatch:");
  if (StartsWith(source, "sim:")) return with_location(SourceSpec::Kind::kSim, "sim:");
  if (EndsWithNoCase(source, ".oni")) {
    spec.kind = SourceSpec::Kind::kOniFile;
    spec.location = source;
    return spec;
  }
  std::error_code ec;
  if (std::filesystem::is_directory(source, ec)) {
    const std::filesystem::path dir(source);
    if (std::filesystem::exists(dir / "rgb.txt", ec)) {
      spec.kind = SourceSpec::Kind::kTum;
      spec.location = source;
      return spec;
    }
    if (std::filesystem::exists(dir / "camera-intrinsics.txt", ec) ||
        std::filesystem::exists(dir.parent_path() / "camera-intrinsics.txt", ec)) {
      spec.kind = SourceSpec::Kind::kThreeDMatch;
      spec.location = source;
      return spec;
    }
    SIGHTMAP_THROW(InvalidArgument, "folder "
                                        << source
                                        << " has neither rgb.txt (TUM) nor camera-intrinsics.txt "
                                           "(3DMatch): "
                                        << kSourceForms);
  }
  SIGHTMAP_THROW(InvalidArgument, "unknown SOURCE '" << source << "': " << kSourceForms);
}

std::unique_ptr<RgbdSource> OpenSource(const std::string& source, const SourceOptions& options) {
  const SourceSpec spec = ParseSourceSpec(source);
  switch (spec.kind) {
    case SourceSpec::Kind::kOpenNi:
      return OpenOpenNiDevice(spec.location, options);
    case SourceSpec::Kind::kOniFile:
      return OpenOniFile(spec.location, options);
    case SourceSpec::Kind::kTum:
      return OpenTumFolder(spec.location, options);
    case SourceSpec::Kind::kThreeDMatch:
      return OpenThreeDMatchFolder(spec.location, options);
    case SourceSpec::Kind::kSim:
      if (!options.calibration_file.empty()) {
        SIGHTMAP_THROW(InvalidArgument,
                       "--calib " << options.calibration_file
                                  << " does not apply to the simulator, whose camera is exact "
                                     "(set in the scene file); drop --calib");
      }
      if (const SourceOpener opener = FindOpener(spec.kind)) return opener(spec.location, options);
      // A program that links sim/ but never called sim::RegisterSimSource(): its bug, not the
      // user's.
      SIGHTMAP_THROW(Error, "sim:" << spec.location
                                   << " cannot be opened: this program did not register the "
                                      "simulator's source (sim::RegisterSimSource()); map a "
                                      "recording (FILE.oni, tum:DIR, 3dmatch:DIR) instead");
  }
  SIGHTMAP_THROW(Error, "unhandled SOURCE kind for " << source);
}

SIGHTMAP_OPTIONS_JSON(SourceOptions, width, height, fps, realtime, sync_tolerance_ns,
                      frame_timeout_ms, calibration_file)

}  // namespace sightmap::capture
