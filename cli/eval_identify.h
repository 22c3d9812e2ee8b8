// `sightmap eval identify --model M --queries DIR [--json] [--plot PNG] [--limit N] [--config F]`:
// locates every phone photo of a simulator query set against the model (the Locator loaded once,
// as `serve` does, with the locator options of --config) and reports the paper's Section 5
// figures (identify/identify_eval.h). Kept apart from eval_command.cc, which only registers the
// subcommand.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "identify/locator.h"

namespace sightmap::cli {

struct EvalIdentifyArgs {
  std::string model_path;
  std::string queries_path;
  std::string plot_path;
  std::string plot_size = "1200x560";
  bool json = false;
  int limit = 0;           // 0 = every photo
  std::string photos_out;  // one JSON line per photo (identify::PhotoRows); empty = none
  bool without_synthetic_views = false;  // locate against keyframes only
  // Search the keyframes that saw each photo's view before retrieval's ranking: what the
  // locator answers when retrieval is perfect (a measurement; the ids come from ground truth).
  bool seeing_keyframes_first = false;
  identify::LocatorOptions locator;  // --config FILE (as `locate --print-config` prints)
};

// Adds the `identify` subcommand to `eval`, filling `args` when parsed.
CLI::App* AddEvalIdentify(CLI::App& eval, EvalIdentifyArgs& args);

// Runs it; returns the exit code. Throws sightmap::Error on runtime failures.
int RunEvalIdentify(const EvalIdentifyArgs& args);

}  // namespace sightmap::cli
