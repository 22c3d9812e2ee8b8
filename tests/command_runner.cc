#include "tests/command_runner.h"

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "tests/test_data.h"

namespace sightmap::testing {

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

CommandResult RunCommand(const std::string& binary, const std::string& args) {
  const std::string dir = MakeTempDir("run");
  const std::string command =
      binary + " " + args + " > " + dir + "/out 2> " + dir + "/err < /dev/null";
  const int status = std::system(command.c_str());
  CommandResult run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  run.out = Slurp(dir + "/out");
  run.err = Slurp(dir + "/err");
  return run;
}

}  // namespace sightmap::testing
