// Runs the built `sightmap` binary for the end-to-end tests (cli_test, map_test).
#pragma once

#include <string>

namespace sightmap::testing {

struct CommandResult {
  int exit_code = -1;  // 128 + signal when the process was killed
  std::string out;
  std::string err;
};

// The whole content of a file ("" when it cannot be read).
std::string Slurp(const std::string& path);

// Runs `binary ARGS` through the shell (ARGS as written, so quoting is the caller's) with no
// standard input, and returns its exit code and both outputs.
CommandResult RunCommand(const std::string& binary, const std::string& args);

}  // namespace sightmap::testing
