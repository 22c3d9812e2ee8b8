#include "core/format.h"

#include <iomanip>
#include <sstream>

namespace sightmap {

std::string Fixed(double value, int digits) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(digits) << value;
  return text.str();
}

}  // namespace sightmap
