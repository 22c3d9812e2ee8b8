#include "core/check.h"

namespace sightmap {

Error::Error(const std::string& message, const char* file, int line)
    : std::runtime_error(message),
      location_(file && *file ? std::string(file) + ":" + std::to_string(line) : std::string()) {}

}  // namespace sightmap
