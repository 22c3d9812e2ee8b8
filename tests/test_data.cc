#include "tests/test_data.h"

#include <cstdlib>
#include <filesystem>

namespace sightmap::testing {

std::string SharedDataDir() {
  if (const char* dir = std::getenv("SIGHTMAP_DATA_DIR"); dir && *dir) return dir;
  return SIGHTMAP_SHARED_DATA_DIR;
}

std::string FindSharedData(const std::string& relative) {
  const std::filesystem::path path = std::filesystem::path(SharedDataDir()) / relative;
  std::error_code ec;
  return std::filesystem::exists(path, ec) ? path.lexically_normal().string() : std::string();
}

bool RunningUnderCi() {
  const char* ci = std::getenv("CI");
  return ci && *ci && std::string(ci) != "false" && std::string(ci) != "0";
}

std::string MakeTempDir(const std::string& name) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::filesystem::path dir = std::filesystem::temp_directory_path() / "sightmap_tests";
  if (info) dir /= std::string(info->test_suite_name()) + "." + info->name();
  dir /= name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

}  // namespace sightmap::testing
