#include "core/link_type.h"

namespace sightmap {

const char* LinkTypeName(LinkType type) {
  switch (type) {
    case LinkType::kOdometry:
      return "odometry";
    case LinkType::kLoopClosure:
      return "loop";
    case LinkType::kRelocalisation:
      return "relocalisation";
    case LinkType::kUser:
      return "user";
    case LinkType::kPrior:
      return "prior";
  }
  return "unknown";
}

}  // namespace sightmap
