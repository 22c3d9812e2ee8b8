#include "core/tum_format.h"

#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/check.h"
#include "tests/test_data.h"

namespace sightmap {
namespace {

TEST(TumFormat, TimestampsParseExactlyAndRoundAtTheTenthDigit) {
  TimestampNs ns = 0;
  ASSERT_TRUE(ParseTimestampNs("1305031102.175304", &ns));
  EXPECT_EQ(ns, 1305031102175304000);  // a double would be off by tens of nanoseconds
  ASSERT_TRUE(ParseTimestampNs("0.0000000004", &ns));
  EXPECT_EQ(ns, 0);
  ASSERT_TRUE(ParseTimestampNs("0.0000000015", &ns));
  EXPECT_EQ(ns, 2);
  ASSERT_TRUE(ParseTimestampNs("12", &ns));
  EXPECT_EQ(ns, 12'000'000'000);
  ASSERT_TRUE(ParseTimestampNs(".5", &ns));
  EXPECT_EQ(ns, 500'000'000);
  ASSERT_TRUE(ParseTimestampNs("-1.25", &ns));
  EXPECT_EQ(ns, -1'250'000'000);
  ASSERT_TRUE(ParseTimestampNs("1.5e3", &ns));
  EXPECT_EQ(ns, 1'500'000'000'000);
  for (const char* bad : {"", ".", "abc", "1.2.3", "1e400", "99999999999", "nan", "1 2"}) {
    EXPECT_FALSE(ParseTimestampNs(bad, &ns)) << bad;
  }
  EXPECT_EQ(FormatTimestamp(1305031102175304001), "1305031102.175304001");
  EXPECT_EQ(FormatTimestamp(-1'250'000'000), "-1.250000000");
}

TEST(TumFormat, ATrajectoryRoundTripsExactlyInTimeAndToTheNanometre) {
  const std::string path = testing::MakeTempDir("tum") + "/trajectory.txt";
  std::vector<StampedPose> poses(3);
  poses[0].timestamp_ns = 1305031102175304123;
  poses[1].timestamp_ns = 1305031102208804999;
  poses[1].world_from_cam = Eigen::Translation3d(1.25, -2.5, 0.123456789) *
                            Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -1.0, 0.2).normalized());
  poses[2].timestamp_ns = 1305031103000000000;
  poses[2].world_from_cam.translation() = Eigen::Vector3d(1e3, 0, -1e-9);
  WriteTumTrajectory(path, poses, "a comment");
  const std::vector<StampedPose> read = ReadTumTrajectory(path);
  ASSERT_EQ(read.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(read[i].timestamp_ns, poses[i].timestamp_ns);
    EXPECT_LT((read[i].world_from_cam.translation() - poses[i].world_from_cam.translation()).norm(),
              1e-9);
    EXPECT_LT((read[i].world_from_cam.linear() - poses[i].world_from_cam.linear()).norm(), 1e-11);
  }
}

TEST(TumFormat, CommasCommentsAndBlankLinesAreReadAndABadLineIsNamed) {
  const std::string dir = testing::MakeTempDir("tum-read");
  std::ofstream(dir + "/ok.txt") << "# comment\n\n1.5,1,2,3,0,0,0,2\r\n2.5 1 2 3 0 0 0 1\n";
  const std::vector<StampedPose> read = ReadTumTrajectory(dir + "/ok.txt");
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].timestamp_ns, 1'500'000'000);
  EXPECT_TRUE(read[0].world_from_cam.linear().isIdentity(1e-12)) << "normalised";
  for (const char* bad : {"1.5 1 2 3 0 0 0\n", "1.5 1 2 3 0 0 0 0\n", "x 1 2 3 0 0 0 1\n"}) {
    std::ofstream(dir + "/bad.txt") << "# first\n" << bad;
    try {
      ReadTumTrajectory(dir + "/bad.txt");
      ADD_FAILURE() << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.txt:2: expected"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(ReadTumTrajectory(dir + "/missing.txt"), Error);
}

}  // namespace
}  // namespace sightmap
