#include "core/input_file.h"

#include <filesystem>
#include <system_error>

#include "core/check.h"

namespace sightmap {

void RefuseFolder(const std::string& path, const std::string& what) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) {
    SIGHTMAP_THROW(InvalidArgument, what << " " << path << " is a folder: give a file");
  }
}

std::ifstream OpenInputFile(const std::string& path, const std::string& what,
                            std::ios::openmode mode) {
  RefuseFolder(path, what);
  return std::ifstream(path, mode | std::ios::in);
}

}  // namespace sightmap
