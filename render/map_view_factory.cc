#include "render/map_view_factory.h"

#include <cstdlib>
#include <string>

#include "core/check.h"

namespace sightmap::render {
namespace {

bool HasDisplay() {
  const char* x11 = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  return (x11 != nullptr && *x11 != '\0') || (wayland != nullptr && *wayland != '\0');
}

std::string OffscreenTarget(const MapViewOptions& options) {
  return options.progress.png_path.empty() ? std::string("off-screen")
                                           : "off-screen to " + options.progress.png_path;
}

}  // namespace

std::unique_ptr<MapView> CreateMapView(const MapViewOptions& options, std::ostream* notices) {
  switch (options.mode) {
    case ViewMode::kHeadless:
      return std::make_unique<ProgressWriter>(options.progress);
    case ViewMode::kPreview:
      return std::make_unique<PreviewWindow>(options.preview);
    case ViewMode::kAuto:
      break;
  }
  std::string reason;
  if (!HasDisplay()) {
    reason = "no display ($DISPLAY is not set)";
  } else {
    try {
      return std::make_unique<PreviewWindow>(options.preview);
    } catch (const Error& e) {
      reason = std::string("cannot open the preview window: ") + e.what();
      // One line: keep the first line of the reason.
      reason = reason.substr(0, reason.find('\n'));
    }
  }
  if (notices != nullptr) {
    *notices << "sightmap: " << reason << "; drawing progress " << OffscreenTarget(options) << "\n";
  }
  return std::make_unique<ProgressWriter>(options.progress);
}

}  // namespace sightmap::render
