#include "mapping/feature_conversion.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::mapping {
namespace {

Features ThreeFeatures() {
  Features features;
  features.keypoints = {cv::KeyPoint(10.f, 20.f, 31.f),
                        cv::KeyPoint(5.5f, 6.5f, 12.f, 45.f, 0.f, 2),
                        cv::KeyPoint(100.f, 200.f, 31.f)};
  features.descriptors = cv::Mat(3, 32, CV_8U);
  cv::randu(features.descriptors, 0, 256);
  features.points_cam = {Eigen::Vector3d(0.1, -0.2, 1.5), Eigen::Vector3d::Zero(),
                         Eigen::Vector3d(-1.0, 0.5, 3.25)};
  features.has_point = {true, false, true};
  return features;
}

TEST(FeatureConversion, PointlessKeypointsBecomeNaNAndBack) {
  const Features original = ThreeFeatures();
  const KeyframeFeatures stored = ToStoreFeatures(original);
  ASSERT_EQ(stored.cam_points.size(), 3u);
  EXPECT_TRUE(stored.cam_points[0].allFinite());
  EXPECT_TRUE(std::isnan(stored.cam_points[1].x()));
  EXPECT_FLOAT_EQ(stored.cam_points[2].z(), 3.25f);

  const Features back = FromStoreFeatures(stored);
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back.has_point, original.has_point);
  EXPECT_EQ(back.NumPoints(), 2u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back.keypoints[i].pt, original.keypoints[i].pt);
    EXPECT_EQ(back.keypoints[i].octave, original.keypoints[i].octave);
    if (original.has_point[i]) {
      EXPECT_NEAR((back.points_cam[i] - original.points_cam[i]).norm(), 0.0, 1e-6);
    }
  }
  EXPECT_EQ(cv::norm(back.descriptors, original.descriptors, cv::NORM_HAMMING), 0.0);
}

TEST(FeatureConversion, InconsistentFeaturesAreRefused) {
  Features broken = ThreeFeatures();
  broken.has_point.pop_back();
  EXPECT_THROW(ToStoreFeatures(broken), Error);
  KeyframeFeatures stored = ToStoreFeatures(ThreeFeatures());
  stored.cam_points.pop_back();
  EXPECT_THROW(FromStoreFeatures(stored), Error);
}

}  // namespace
}  // namespace sightmap::mapping
