// Opening a file the user named. On Linux a folder opens as an ifstream and fails only at the first
// read (libstdc++ throws "basic_filebuf::underflow ... Is a directory") or reads as empty, which
// readers then reported as "not valid JSON", "has no poses" or an unexpected failure. Every reader
// of a user-given path opens it here, so the mistake gets one answer.
#pragma once

#include <fstream>
#include <string>

namespace sightmap {

// Throws InvalidArgument "<what> <path> is a folder: give a file" when `path` names a folder
// (`what` says what the file is: "photo", "--calib", "trajectory"). Anything else, a missing file
// included, is left to the caller, whose message knows what the file is for.
void RefuseFolder(const std::string& path, const std::string& what);

// RefuseFolder, then the file opened (check is_open(): a missing file is not thrown here).
std::ifstream OpenInputFile(const std::string& path, const std::string& what,
                            std::ios::openmode mode = std::ios::in);

}  // namespace sightmap
