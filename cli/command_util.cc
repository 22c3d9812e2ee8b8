#include "cli/command_util.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>

#include "core/check.h"
#include "core/input_file.h"

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

void AddModelArgument(CLI::App& app, std::string& path) {
  auto* positional = app.add_option("MODEL", path, "the model's SQLite file");
  auto* named = app.add_option("--model", path, "the model's SQLite file (the same as MODEL)");
  positional->excludes(named);
}

int RequireModelArgument(const CLI::App& app, const std::string& path) {
  if (!path.empty()) return -1;
  PrintError("give the model: '" + app.get_name() + " MODEL' or '" + app.get_name() +
             " --model MODEL'");
  return kExitUsage;
}

ImageSize ParseImageSize(const std::string& text, const std::string& option, ImageSize min,
                         int max_side) {
  ImageSize size;
  char x = 0;
  char rest = 0;
  const int read = std::sscanf(text.c_str(), "%d%c%d%c", &size.width, &x, &size.height, &rest);
  if (read != 3 || x != 'x' || size.width < min.width || size.height < min.height ||
      size.width > max_side || size.height > max_side) {
    SIGHTMAP_THROW(InvalidArgument, option << " must be WxH in pixels, from " << min.width << "x"
                                           << min.height << " to " << max_side << "x" << max_side
                                           << ", got '" << text << "'");
  }
  return size;
}

CLI::Validator Within(double min, double max, const std::string& unit) {
  std::ostringstream range;
  range << "from " << min << " to " << max << (unit.empty() ? "" : " ") << unit;
  const std::string text = range.str();
  return CLI::Validator(
      [min, max, text](std::string& input) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(input.c_str(), &end);
        const bool number = !input.empty() && end == input.c_str() + input.size();
        if (!number || !std::isfinite(value)) return "'" + input + "' is not a number " + text;
        if (value < min || value > max) return input + " is out of range: must be " + text;
        return std::string();
      },
      "NUMBER " + text);
}

CLI::Validator WholeNumberUpTo(uint64_t max) {
  const std::string text = "a whole number from 0 to " + std::to_string(max);
  return CLI::Validator(
      [max, text](std::string& input) -> std::string {
        uint64_t value = 0;
        const char* end = input.data() + input.size();
        const bool digits = !input.empty() && std::all_of(input.begin(), input.end(), [](char c) {
          return c >= '0' && c <= '9';
        });
        if (!digits || std::from_chars(input.data(), end, value).ptr != end || value > max) {
          return "'" + input + "' must be " + text;
        }
        return std::string();
      },
      "UINT");
}

void MakeParentFolder(const std::string& path, const std::string& option) {
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (folder.empty()) return;
  std::error_code error;
  std::filesystem::create_directories(folder, error);
  if (error) {
    SIGHTMAP_THROW(Error, "cannot write " << option << " " << path << ": cannot create its folder ("
                                          << error.message() << ")");
  }
}

std::string ReadConfigFile(const std::string& path) {
  constexpr std::streamsize kMaxBytes = 1 << 20;
  // Read as a stream, not by its size: `--config /dev/stdin` takes a pipe.
  std::ifstream in = OpenInputFile(path, "--config", std::ios::binary);
  if (!in.is_open()) {
    SIGHTMAP_THROW(InvalidArgument, "--config " << path << ": " << std::strerror(errno));
  }
  std::string text(static_cast<size_t>(kMaxBytes) + 1, '\0');
  in.read(text.data(), kMaxBytes + 1);
  text.resize(static_cast<size_t>(in.gcount()));
  if (static_cast<std::streamsize>(text.size()) > kMaxBytes) {
    SIGHTMAP_THROW(InvalidArgument,
                   "--config " << path << " is over 1 MiB; a config is a small JSON file");
  }
  return text;
}

int RequireGiven(const CLI::App& app, std::initializer_list<const CLI::Option*> options) {
  for (const CLI::Option* option : options) {
    if (option->count() == 0) {
      PrintError(option->get_name() + " is required — run '" + app.get_name() + " --help'");
      return kExitUsage;
    }
  }
  return -1;
}

void CheckOutputFile(const std::string& path, const std::string& option) {
  if (path.empty()) return;
  namespace fs = std::filesystem;
  std::error_code error;
  if (fs::is_directory(path, error)) {
    SIGHTMAP_THROW(InvalidArgument,
                   option << " " << path << " is a folder: give a file name in it");
  }
  MakeParentFolder(path, option);
  const bool existed = fs::exists(path, error);
  // O_NONBLOCK: a named pipe without a reader fails at once instead of blocking here.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_NONBLOCK | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int reason = errno;
    SIGHTMAP_THROW(Error,
                   "cannot write " << option << " " << path << ": " << std::strerror(reason));
  }
  ::close(fd);
  if (!existed) fs::remove(path, error);
}

void CheckOutputFolder(const std::string& dir, const std::string& option) {
  if (dir.empty()) return;
  namespace fs = std::filesystem;
  std::error_code error;
  if (fs::exists(dir, error) && !fs::is_directory(dir, error)) {
    SIGHTMAP_THROW(InvalidArgument, option << " " << dir << " is a file, not a folder");
  }
  fs::create_directories(dir, error);
  if (error) {
    SIGHTMAP_THROW(Error, "cannot create " << option << " " << dir << ": " << error.message());
  }
  const std::string probe =
      (fs::path(dir) / (".sightmap-write-test-" + std::to_string(::getpid()))).string();
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int reason = errno;
    SIGHTMAP_THROW(Error,
                   "cannot write in " << option << " " << dir << ": " << std::strerror(reason));
  }
  ::close(fd);
  fs::remove(probe, error);
}

void PrintError(const std::string& message) {
  std::string line = message;
  std::replace(line.begin(), line.end(), '\n', ' ');
  std::cerr << "error: " << line << std::endl;
}

std::function<void(int64_t, int64_t)> TenthsProgress(const std::string& what,
                                                     const std::string& unit) {
  const bool tty = ::isatty(2) != 0;
  return [what, unit, tty, reported_tenth = int64_t{-1}](int64_t done, int64_t total) mutable {
    const int64_t tenth = total > 0 ? 10 * done / total : 10;
    if (tenth == reported_tenth) return;
    reported_tenth = tenth;
    std::cerr << (tty ? "\r" : "") << what << ": " << done << "/" << total << " " << unit
              << (tty && done < total ? "" : "\n") << std::flush;
  };
}

}  // namespace sightmap::cli
