// Chooses where progress goes: the preview window or off-screen images.
//   kPreview  the window, or sightmap::Error if it cannot open (the user asked for it);
//   kHeadless off-screen (ProgressWriter), no window even with a display;
//   kAuto     the window when $DISPLAY (or $WAYLAND_DISPLAY) is set and GLFW opens a window,
//             else off-screen, with a one-line notice saying why.
#pragma once

#include <memory>
#include <ostream>

#include "render/map_view.h"
#include "render/preview_window.h"
#include "render/progress_writer.h"

namespace sightmap::render {

enum class ViewMode { kAuto, kPreview, kHeadless };

struct MapViewOptions {
  ViewMode mode = ViewMode::kAuto;
  PreviewOptions preview;
  ProgressWriterOptions progress;  // png_path empty = render off-screen but write no file
};

// `notices` receives the fallback notice (one line), e.g. &std::cerr; may be null.
std::unique_ptr<MapView> CreateMapView(const MapViewOptions& options, std::ostream* notices);

}  // namespace sightmap::render
