// What made a link between two keyframes: the mapper makes them, the pose graph weighs them by it
// (odometry and priors hold the map together, the others are checked as loops), the model stores
// it (the numbers are the schema's: never renumber).
#pragma once

#include <Eigen/Core>

namespace sightmap {

// A link's information (inverse covariance) over (tx, ty, tz, rx, ry, rz) [1/m^2, 1/rad^2].
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// kPrior: the tracker's motion model across a blind stretch (no registration behind it).
// kUser: a link a person asserted; it constrains the graph like a verified loop.
enum class LinkType { kOdometry = 0, kLoopClosure = 1, kRelocalisation = 2, kUser = 3, kPrior = 4 };
// "odometry", "loop", "relocalisation", "user", "prior".
const char* LinkTypeName(LinkType type);

}  // namespace sightmap
