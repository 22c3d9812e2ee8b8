// Live OpenNI2 devices (Kinect v1 with a driver, Xtion, Carmine) and .oni recordings, through the
// real OpenNI2 library and its own file driver. Both share one reader: a recording is a device
// whose frames come from a file.
#pragma once

#include <memory>
#include <string>

#include "capture/rgbd_source.h"

namespace sightmap::capture {

// `uri` empty opens the first device OpenNI2 lists. Throws sightmap::Error when there is none
// ("no RGB-D sensor found — run 'sightmap devices'") or it cannot be opened.
std::unique_ptr<RgbdSource> OpenOpenNiDevice(const std::string& uri, const SourceOptions& options);

// Plays `path` as fast as the consumer reads (or at the recorded pace with options.realtime), once.
// Throws sightmap::Error with a one-line reason when the file is missing, empty, not an ONI file,
// of the 1.0.0 format OpenNI2 cannot play, or holds no frames.
std::unique_ptr<RgbdSource> OpenOniFile(const std::string& path, const SourceOptions& options);

}  // namespace sightmap::capture
