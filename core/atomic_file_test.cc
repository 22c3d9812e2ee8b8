#include "core/atomic_file.h"

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/check.h"
#include "tests/command_runner.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

using testing::Slurp;

TEST(AtomicFile, ReplacesTheTargetOnlyOnCommit) {
  const std::string path = testing::MakeTempDir("atomic") + "/out.txt";
  WriteFileAtomically(path, "old");
  EXPECT_EQ(Slurp(path), "old");
  {
    AtomicFile file(path);
    file.out() << "new, half written";
    EXPECT_EQ(Slurp(path), "old") << "the target changes only at Commit";
    EXPECT_TRUE(std::filesystem::exists(path + ".tmp"));
  }  // not committed: as if the process had failed before the end
  EXPECT_EQ(Slurp(path), "old");
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  {
    AtomicFile file(path, ".partial");
    EXPECT_EQ(file.temporary_path(), path + ".partial");
    file.out() << "new";
    file.Commit();
  }
  EXPECT_EQ(Slurp(path), "new");
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  const std::string binary("a\0b\xff", 4);
  WriteFileAtomically(path, binary);
  EXPECT_EQ(Slurp(path), binary);
}

TEST(AtomicFile, AMissingFolderIsAClearError) {
  try {
    WriteFileAtomically("/nonexistent-folder/out.txt", "x");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-folder/out.txt"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(SyncFolder("/nonexistent-folder"), Error);
  EXPECT_THROW(SyncFile("/nonexistent-folder/out.txt"), Error);
}

}  // namespace
}  // namespace sightmap
