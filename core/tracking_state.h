// Whether the newest keyframe could be placed in the map: one definition for the mapper that
// decides it and the renderer and status line that show it.
#pragma once

namespace sightmap {

enum class TrackingState {
  kTracking,     // registered to the keyframes before it
  kLost,         // could not be registered: it starts a segment of its own
  kRelocalised,  // its segment was joined to the map through place recognition
};

// "tracking", "lost", "relocalised".
const char* ToString(TrackingState state);

}  // namespace sightmap
