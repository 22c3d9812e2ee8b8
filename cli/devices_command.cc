// sightmap devices [--json]: the RGB-D sensors on USB, whether the current user may open them and
// whether OpenNI2 lists them, with what to do about each problem. No sensor is not a failure.
#include <iostream>

#include <nlohmann/json.hpp>

#include "capture/devices_report.h"
#include "cli/command_util.h"
#include "cli/commands.h"

namespace sightmap::cli {

int RunDevices(int argc, char** argv) {
  CLI::App app(
      "List attached RGB-D sensors, whether you may open them and whether OpenNI2 sees "
      "them.",
      "sightmap devices");
  bool json = false;
  app.add_flag("--json", json, "print one JSON object (stable keys) instead of text");
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;

  const capture::DevicesReport report = capture::ScanDevices();
  if (json) {
    std::cout << capture::DevicesReportToJson(report).dump(2) << std::endl;
  } else {
    std::cout << capture::FormatDevicesReport(report);
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
