// One thin function per `sightmap` subcommand: parse its options, call the libraries, return an
// exit code (see command_util.h). Library errors propagate as exceptions to main().
#pragma once

namespace sightmap::cli {

int RunDevices(int argc, char** argv);
int RunProbe(int argc, char** argv);
int RunInfo(int argc, char** argv);
int RunCoverage(int argc, char** argv);
int RunSynthesize(int argc, char** argv);
int RunExport(int argc, char** argv);
int RunSim(int argc, char** argv);
int RunEval(int argc, char** argv);
int RunMap(int argc, char** argv);
int RunServe(int argc, char** argv);
int RunLabel(int argc, char** argv);
int RunLocate(int argc, char** argv);

}  // namespace sightmap::cli
