// Access to the shared recordings in ../shared/data for tests. They are never copied into the
// project: a test that needs them skips when they are absent, and fails when CI is set.
#pragma once

#include <string>

#include <gtest/gtest.h>

namespace sightmap::testing {

// The shared data folder: $SIGHTMAP_DATA_DIR if set, else the path configured at build time.
std::string SharedDataDir();

// Full path of `relative` under the shared data folder, or "" when it does not exist.
std::string FindSharedData(const std::string& relative);

// True when running under CI (the environment variable CI is set to anything but "" or "false").
bool RunningUnderCi();

// A fresh empty folder, <system temporary folder>/sightmap_tests/<suite>.<test>/<name>, emptied
// when a test asks for it again and otherwise left for inspection after a failure.
std::string MakeTempDir(const std::string& name);

}  // namespace sightmap::testing

// In a TEST body: binds `var` to the data path, or skips (fails under CI) when it is absent.
#define SIGHTMAP_REQUIRE_SHARED_DATA(var, relative)                          \
  const std::string var = ::sightmap::testing::FindSharedData(relative);     \
  if (var.empty()) {                                                         \
    if (::sightmap::testing::RunningUnderCi()) {                             \
      FAIL() << "shared test data " << (relative) << " is missing under "    \
             << ::sightmap::testing::SharedDataDir() << " and CI is set";    \
    }                                                                        \
    GTEST_SKIP() << "shared test data " << (relative) << " not found under " \
                 << ::sightmap::testing::SharedDataDir()                     \
                 << " (clone ../shared beside the project)";                 \
  }
