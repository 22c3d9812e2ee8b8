#include "slam/features.h"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "slam/matching.h"

namespace sightmap::slam {
namespace {

// Grey blobs and boxes of random size and shade: corners and blobs at many scales.
cv::Mat TexturedImage(int width, int height) {
  cv::RNG rng(5);
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(128));
  for (int i = 0; i < 400; ++i) {
    const cv::Point centre(rng.uniform(0, width), rng.uniform(0, height));
    const int size = rng.uniform(3, 30);
    const cv::Scalar shade(rng.uniform(0, 256));
    if (i % 2 == 0) {
      cv::circle(image, centre, size, shade, cv::FILLED);
    } else {
      cv::rectangle(image, centre, centre + cv::Point(size, size * 2 / 3), shade, cv::FILLED);
    }
  }
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.8);
  return image;
}

FeatureOptions RootSift() {
  FeatureOptions options;
  options.type = FeatureOptions::Type::kSift;
  return options;
}

TEST(RootSift, RowsAreUnitNormScaledToBytes) {
  const Features features =
      ExtractFeatures(TexturedImage(640, 480), cv::Mat(),
                      Intrinsics::FromFieldOfView(640, 480, 1.0, 0.0), RootSift());
  ASSERT_GT(features.size(), 300u);
  EXPECT_LE(features.size(), static_cast<size_t>(RootSift().max_features));
  ASSERT_EQ(features.descriptors.type(), CV_8U);
  ASSERT_EQ(features.descriptors.cols, 128);
  ASSERT_EQ(features.descriptors.rows, static_cast<int>(features.size()));
  for (int r = 0; r < features.descriptors.rows; ++r) {
    // Rounding each of 128 components moves the norm by well under 2%.
    EXPECT_NEAR(cv::norm(features.descriptors.row(r), cv::NORM_L2), kRootSiftScale,
                0.02 * kRootSiftScale)
        << r;
  }
}

// The reason for RootSIFT: the same things seen turned and from farther away still match.
TEST(RootSift, MatchesAcrossRotationAndScale) {
  const cv::Mat image = TexturedImage(640, 480);
  const cv::Mat affine = cv::getRotationMatrix2D(cv::Point2f(320, 240), 30.0, 0.7);
  cv::Mat turned;
  cv::warpAffine(image, turned, affine, image.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                 cv::Scalar(128));
  const Intrinsics camera = Intrinsics::FromFieldOfView(640, 480, 1.0, 0.0);
  const Features a = ExtractFeatures(image, cv::Mat(), camera, RootSift());
  const Features b = ExtractFeatures(turned, cv::Mat(), camera, RootSift());
  int kept = 0;
  int right = 0;
  for (const auto& nearest : KNearestEuclidean(a.descriptors, b.descriptors, 2)) {
    ASSERT_EQ(nearest.size(), 2u);
    if (nearest[0].distance > 0.8 * nearest[1].distance) continue;
    ++kept;
    const cv::Point2f p = a.keypoints[static_cast<size_t>(nearest[0].queryIdx)].pt;
    const cv::Point2f expected(
        static_cast<float>(affine.at<double>(0, 0) * p.x + affine.at<double>(0, 1) * p.y +
                           affine.at<double>(0, 2)),
        static_cast<float>(affine.at<double>(1, 0) * p.x + affine.at<double>(1, 1) * p.y +
                           affine.at<double>(1, 2)));
    const cv::Point2f d = b.keypoints[static_cast<size_t>(nearest[0].trainIdx)].pt - expected;
    if (std::hypot(d.x, d.y) < 3.0) ++right;
  }
  EXPECT_GE(right, 150);
  EXPECT_GE(right, 0.9 * kept) << right << " of " << kept;
}

TEST(RootSift, KeypointsOnDepthGetTheirPoints) {
  const cv::Mat image = TexturedImage(320, 240);
  const cv::Mat depth(240, 320, CV_16UC1, cv::Scalar(2000));
  const Intrinsics camera = Intrinsics::FromFieldOfView(320, 240, 1.0, 0.0);
  const Features features = ExtractFeatures(image, depth, camera, RootSift());
  ASSERT_GT(features.size(), 50u);
  ASSERT_TRUE(features.IsConsistent());
  size_t with_point = 0;
  for (size_t i = 0; i < features.size(); ++i) {
    if (!features.has_point[i]) continue;
    ++with_point;
    EXPECT_NEAR(features.points_cam[i].z(), 2.0, 1e-9);
  }
  // Only keypoints within a pixel of the image border lack the depth window.
  EXPECT_GE(with_point, features.size() * 9 / 10);
}

// Tracking, loop closure and the vocabulary take binary descriptors: SLAM refuses SIFT where it
// is chosen, while photos may use it.
TEST(RootSift, SlamRefusesItAndPhotosMayUseIt) {
  std::string why;
  EXPECT_TRUE(RootSift().Check(&why)) << why;
  EXPECT_FALSE(CheckOrbFeatures(RootSift(), &why));
  EXPECT_NE(why.find("ORB"), std::string::npos) << why;
  EXPECT_TRUE(CheckOrbFeatures(FeatureOptions(), &why)) << why;
  FeatureOptions bad = RootSift();
  bad.sift_contrast_threshold = 0.0;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_THROW(ExtractFeatures(TexturedImage(64, 48), cv::Mat(),
                               Intrinsics::FromFieldOfView(64, 48, 1.0, 0.0), bad),
               InvalidArgument);
}

}  // namespace
}  // namespace sightmap::slam
