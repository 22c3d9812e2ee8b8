#include "core/input_file.h"

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap {
namespace {

TEST(OpenInputFile, AFolderIsRefusedByNameAndAMissingFileIsLeftToTheCaller) {
  const std::string dir = ::testing::TempDir();
  try {
    OpenInputFile(dir, "--calib");
    FAIL() << "a folder was opened";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(std::string(e.what()), "--calib " + dir + " is a folder: give a file");
  }
  EXPECT_THROW(RefuseFolder(dir, "photo"), InvalidArgument);
  EXPECT_FALSE(OpenInputFile(dir + "/no-such-file.txt", "trajectory").is_open());
  EXPECT_NO_THROW(RefuseFolder(dir + "/no-such-file.txt", "trajectory"));
}

}  // namespace
}  // namespace sightmap
