// What every `sightmap` subcommand shares: the exit-code contract and CLI11 parsing.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace sightmap::cli {

// Exit codes of every command.
constexpr int kExitSuccess = 0;
constexpr int kExitFailure = 1;  // runtime failure, with one `error: ...` line on stderr
constexpr int kExitUsage = 2;    // bad command line

// Parses argv into `app`. Returns -1 when the command should run, else the exit code to return
// (0 after --help, kExitUsage after a usage error, which it prints).
int ParseOrExit(CLI::App& app, int argc, char** argv);

// Prints `error: <message>` as one line on stderr.
void PrintError(const std::string& message);

}  // namespace sightmap::cli
