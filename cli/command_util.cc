#include "cli/command_util.h"

#include <algorithm>
#include <iostream>

namespace sightmap::cli {

int ParseOrExit(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return kExitSuccess;
  } catch (const CLI::CallForAllHelp&) {
    std::cout << app.help("", CLI::AppFormatMode::All);
    return kExitSuccess;
  } catch (const CLI::ParseError& e) {
    PrintError(std::string(e.what()) + " — run '" + app.get_name() + " --help'");
    return kExitUsage;
  }
  return -1;
}

void PrintError(const std::string& message) {
  std::string line = message;
  std::replace(line.begin(), line.end(), '\n', ' ');
  std::cerr << "error: " << line << std::endl;
}

}  // namespace sightmap::cli
