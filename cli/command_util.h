// What every `sightmap` subcommand shares: the exit-code contract and CLI11 parsing.
#pragma once

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "core/options_json.h"

namespace sightmap::cli {

// Exit codes of every command.
constexpr int kExitSuccess = 0;
constexpr int kExitFailure = 1;  // runtime failure, with one `error: ...` line on stderr
constexpr int kExitUsage = 2;    // bad command line

// Parses argv into `app`. Returns -1 when the command should run, else the exit code to return
// (0 after --help, kExitUsage after a usage error, which it prints).
int ParseOrExit(CLI::App& app, int argc, char** argv);

// The model a read command works on, as `MODEL` (positional) or `--model MODEL` like every other
// command; RequireModelArgument after parsing returns kExitUsage (printed) when neither or both
// were given, else -1.
void AddModelArgument(CLI::App& app, std::string& path);
int RequireModelArgument(const CLI::App& app, const std::string& path);

// "WxH" [px] for `option`, each side from min to max; throws InvalidArgument naming the option,
// the form and the limits (an image of 100000x100000 would need 30 GB before anything is drawn).
struct ImageSize {
  int width = 0;
  int height = 0;
};
ImageSize ParseImageSize(const std::string& text, const std::string& option, ImageSize min,
                         int max_side);

// A number option's check: a finite number from `min` to `max` (both included), in `unit` when
// given. The message names the range as a person would ("must be a number from 0 to 1000 Hz");
// CLI11's own Range lets NaN through and NonNegativeNumber prints DBL_MAX in 300 digits.
CLI::Validator Within(double min, double max, const std::string& unit = "");

// A whole number from 0 to `max`, digits only: CLI11 reads "-1" into an unsigned option as the
// largest value.
CLI::Validator WholeNumberUpTo(uint64_t max);

// Makes the folder `path` (given by `option`) goes in, when it is missing; throws Error naming
// the option when it cannot.
void MakeParentFolder(const std::string& path, const std::string& option);

// Checks, before any work, that `path` (given by `option`, e.g. "--ply") can be written: not a
// folder, its folder made if missing, and the file creatable or writable. Probes with an
// append-open that changes no existing file and removes a file it created. Throws InvalidArgument
// for a folder given as a file, Error with the system's reason otherwise. No-op for "".
void CheckOutputFile(const std::string& path, const std::string& option);
// The same for an output folder: made if missing, and a file can be created in it.
void CheckOutputFolder(const std::string& dir, const std::string& option);

// The text of a config file; throws InvalidArgument when it cannot be read or is over 1 MiB.
std::string ReadConfigFile(const std::string& path);

// `--config FILE` and `--print-config`. The file holds `options` as JSON (what `--print-config`
// prints, and `info --json` shows of a map session) and is read while the command line is parsed:
// CLI11 assigns the other flags after parsing, so a flag on the command line overrides the file
// whatever their order. A key the file leaves out keeps its default. Errors (a missing file, bad
// JSON, an unknown key) throw InvalidArgument naming the file and the key. `print_config` is set
// by `--print-config`: print every option (PrintConfig) and do nothing else. AddConfigOption
// adds `--config` alone, for a command that reads another command's options.
template <typename Options>
void AddConfigOption(CLI::App& app, Options& options, const std::string& description) {
  app.add_option_function<std::string>(
         "--config",
         [&options](const std::string& path) {
           options_json::ParseInto(ReadConfigFile(path), "--config " + path, options);
         },
         description)
      ->trigger_on_parse();
}
template <typename Options>
void AddConfigOptions(CLI::App& app, Options& options, bool& print_config) {
  AddConfigOption(
      app, options,
      "read the options from this JSON file (see --print-config); flags given here override it");
  app.add_flag("--print-config", print_config,
               "print every option as the JSON --config reads (after --config and the flags), "
               "and exit");
}
// Prints `options` as --config reads them; returns kExitSuccess.
template <typename Options>
int PrintConfig(const Options& options) {
  std::cout << nlohmann::json(options).dump(2) << "\n";
  return kExitSuccess;
}
// The options a command needs unless it only prints its config: returns kExitUsage (printed as
// CLI11 prints a missing required option) when one of them was not given, else -1.
int RequireGiven(const CLI::App& app, std::initializer_list<const CLI::Option*> options);

// Prints `error: <message>` as one line on stderr.
void PrintError(const std::string& message);

// Progress of long work on stderr, "<what>: done/total <unit>" every tenth: one line redrawn on a
// terminal, a line per tenth in a log.
std::function<void(int64_t, int64_t)> TenthsProgress(const std::string& what,
                                                     const std::string& unit);

}  // namespace sightmap::cli
