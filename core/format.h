// Numbers as the command line's tables and messages print them.
#pragma once

#include <string>

namespace sightmap {

// `value` with exactly `digits` digits after the point ("0.40" for 0.4 and 2).
std::string Fixed(double value, int digits);

}  // namespace sightmap
