// sightmap: indoor RGB-D mapping and appliance identification. `sightmap --help` lists commands.
#include <cstring>
#include <exception>
#include <iostream>
#include <string>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "cli/version.h"
#include "core/check.h"
#include "sim/sim_source.h"

namespace {

struct Command {
  const char* name;
  int (*run)(int argc, char** argv);
  const char* summary;
};

constexpr Command kCommands[] = {
    {"map", sightmap::cli::RunMap,
     "map a SOURCE into a MODEL (keyframes, loops, PLY), resuming a model that has keyframes"},
    {"devices", sightmap::cli::RunDevices,
     "list attached RGB-D sensors, whether you may open them and whether OpenNI2 sees them"},
    {"probe", sightmap::cli::RunProbe,
     "read a SOURCE to its end and report its streams, intrinsics and frame counts"},
    {"info", sightmap::cli::RunInfo,
     "report what a MODEL holds: sessions, keyframes, links, labels, size"},
    {"coverage", sightmap::cli::RunCoverage,
     "from which directions a MODEL's keyframes saw each labelled appliance, and what they missed"},
    {"synthesize", sightmap::cli::RunSynthesize,
     "render views of labelled appliances from the directions the walk missed, for photos"},
    {"export", sightmap::cli::RunExport,
     "write a MODEL's point cloud (PLY), trajectory (TUM) and labels (point lists)"},
    {"label", sightmap::cli::RunLabel,
     "the appliance labels of a MODEL: 'label add|import|list|remove|export'"},
    {"sim", sightmap::cli::RunSim,
     "the synthetic building: 'sim generate' writes a ground-truth walk and phone photos"},
    {"locate", sightmap::cli::RunLocate,
     "locate a phone PHOTO against a MODEL and list the labelled appliances in view"},
    {"eval", sightmap::cli::RunEval,
     "'eval trajectory': ATE and RPE against ground truth; 'eval identify': the paper's figures"},
    {"serve", sightmap::cli::RunServe,
     "answer phone photos over HTTP: POST /locate, GET /appliances, GET /health"},
};

void PrintUsage(std::ostream& out) {
  out << "sightmap " << SIGHTMAP_VERSION
      << " — indoor RGB-D mapping and appliance identification\n\n"
         "Usage: sightmap <command> [options]   (sightmap <command> --help for its options)\n\n"
         "Commands:\n";
  for (const Command& command : kCommands) {
    out << "  " << command.name << std::string(12 - std::strlen(command.name), ' ')
        << command.summary << "\n";
  }
  out << "\nSOURCE is openni:// (first sensor), openni://URI, FILE.oni, tum:DIR, 3dmatch:DIR or\n"
         "sim:NAME[?key=value&...] (the synthetic building).\n"
         "Exit codes: 0 success, 1 runtime failure, 2 usage error.\n";
}

}  // namespace

int main(int argc, char** argv) {
  using sightmap::cli::kExitFailure;
  using sightmap::cli::kExitUsage;
  sightmap::sim::RegisterSimSource();  // makes sim:NAME sources open the simulator
  if (argc < 2) {
    PrintUsage(std::cerr);
    return kExitUsage;
  }
  const std::string name = argv[1];
  if (name == "--help" || name == "-h" || name == "help") {
    PrintUsage(std::cout);
    return 0;
  }
  if (name == "--version" || name == "-V") {
    std::cout << "sightmap " << SIGHTMAP_VERSION << "\n";
    return 0;
  }
  for (const Command& command : kCommands) {
    if (name != command.name) continue;
    try {
      // The command sees itself as argv[0], so its --help reads "sightmap probe ...".
      return command.run(argc - 1, argv + 1);
    } catch (const sightmap::InvalidArgument& e) {
      sightmap::cli::PrintError(e.what());
      return kExitUsage;
    } catch (const sightmap::Error& e) {
      sightmap::cli::PrintError(e.what());
      return kExitFailure;
    } catch (const std::exception& e) {
      sightmap::cli::PrintError(std::string("unexpected failure: ") + e.what() +
                                " — please report this with the command you ran");
      return kExitFailure;
    }
  }
  sightmap::cli::PrintError("unknown command '" + name + "' — run 'sightmap --help'");
  return kExitUsage;
}
