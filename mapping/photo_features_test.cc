#include "mapping/photo_features.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "store/synthetic_model.h"
#include "tests/test_data.h"

namespace sightmap::mapping {
namespace {

// A keyframe of discs on grey at 1.5 m: RootSIFT finds plenty, each with a point.
store::KeyframeRecord TexturedKeyframe(SessionId session, int index) {
  store::SyntheticKeyframeOptions options;
  options.width = 640;
  options.height = 480;
  store::KeyframeRecord keyframe = store::MakeSyntheticKeyframe(session, index, options);
  keyframe.color = cv::Mat(480, 640, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::RNG rng(static_cast<uint64_t>(index) + 5);
  for (int i = 0; i < 300; ++i) {
    const cv::Point centre(rng.uniform(0, 640), rng.uniform(0, 480));
    cv::circle(keyframe.color, centre, rng.uniform(3, 20), cv::Scalar::all(rng.uniform(0, 256)),
               cv::FILLED);
  }
  keyframe.depth = cv::Mat(480, 640, CV_16UC1, cv::Scalar(1500));
  return keyframe;
}

TEST(PhotoFeatures, OnlyFeaturesWithAPointAtTheMatchersScale) {
  const store::KeyframeRecord keyframe = TexturedKeyframe(SessionId(1), 0);
  cv::Mat depth = keyframe.depth.clone();
  depth(cv::Rect(0, 0, 320, 480)).setTo(0);  // the left half has no depth
  PhotoFeatureExtraction extraction;
  const Features features =
      ExtractPhotoFeatures(keyframe.color, depth, keyframe.intrinsics, extraction);
  ASSERT_GT(features.size(), 50u);
  EXPECT_EQ(features.descriptors.cols, 128);
  EXPECT_EQ(features.NumPoints(), features.size());
  for (const cv::KeyPoint& keypoint : features.keypoints) {
    EXPECT_GE(keypoint.pt.x, 158.0f);  // the right half of the 640-px-wide image, less a margin
  }
  PhotoFeatureExtraction orb;
  orb.features.type = slam::FeatureOptions::Type::kOrb;
  std::string error;
  EXPECT_FALSE(orb.Check(&error));
  EXPECT_THROW(AddMissingPhotoFeatures(nullptr, extraction), Error);
}

// A model mapped before photo features existed gets them for every keyframe with images, one
// transaction each: a second run has nothing left to do, and keyframes that had them keep theirs.
TEST(PhotoFeatures, AddMissingStoresThemForEachKeyframeOnce) {
  const std::string path = testing::MakeTempDir("photo-features") + "/model.db";
  store::Model model = store::Model::Open(path);
  const SessionId session = model.BeginSession({});
  std::vector<KeyframeId> ids;
  for (int i = 0; i < 3; ++i) ids.push_back(model.AddKeyframe(TexturedKeyframe(session, i)));
  Features kept;
  kept.keypoints.emplace_back(1.0f, 2.0f, 3.0f);
  kept.descriptors = cv::Mat(1, 128, CV_8U, cv::Scalar(9));
  kept.points_cam.emplace_back(0.0, 0.0, 1.0);
  kept.has_point.push_back(true);
  model.SetPhotoFeatures(ids[1], kept);

  std::vector<std::pair<int64_t, int64_t>> calls;
  const int64_t added = AddMissingPhotoFeatures(
      &model, PhotoFeatureExtraction(),
      [&](int64_t done, int64_t total) { calls.emplace_back(done, total); });
  EXPECT_EQ(added, 2);
  ASSERT_EQ(calls.size(), 2u);
  EXPECT_EQ(calls[0], std::make_pair(int64_t{1}, int64_t{2}));
  EXPECT_EQ(calls[1], std::make_pair(int64_t{2}, int64_t{2}));
  EXPECT_EQ(model.NumKeyframesWithPhotoFeatures(), 3);
  for (KeyframeId id : {ids[0], ids[2]}) {
    const std::optional<Features> stored = model.LoadPhotoFeatures(id);
    ASSERT_TRUE(stored.has_value());
    EXPECT_GT(stored->size(), 50u);
    EXPECT_EQ(stored->NumPoints(), stored->size());
  }
  EXPECT_EQ(model.LoadPhotoFeatures(ids[1])->size(), 1u);
  EXPECT_EQ(AddMissingPhotoFeatures(&model, PhotoFeatureExtraction()), 0);
}

}  // namespace
}  // namespace sightmap::mapping
