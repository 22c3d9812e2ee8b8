#include "core/tracking_state.h"

namespace sightmap {

const char* ToString(TrackingState state) {
  switch (state) {
    case TrackingState::kTracking:
      return "tracking";
    case TrackingState::kLost:
      return "lost";
    case TrackingState::kRelocalised:
      return "relocalised";
  }
  return "unknown";
}

}  // namespace sightmap
