// Runs the built `sightmap` binary for the end-to-end tests, and checks what its errors look like.
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

// `sightmap ARGS`: the binary this build made.
CommandResult Sightmap(const std::string& args);

// Newlines in `text`.
int CountLines(const std::string& text);

// The project's error contract: exit `exit_code` with exactly one line on stderr, "error: ...",
// holding `fragment`.
void ExpectOneLineError(const CommandResult& run, int exit_code, const std::string& fragment);

}  // namespace sightmap::testing
