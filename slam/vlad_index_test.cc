#include "slam/vlad_index.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/check.h"
#include "slam/features.h"

namespace sightmap::slam {
namespace {

// Non-negative unit-length 128-vectors (RootSIFT's shape): the "things" images show.
std::vector<cv::Mat> Prototypes(int count, std::mt19937* rng) {
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  std::vector<cv::Mat> prototypes;
  for (int p = 0; p < count; ++p) {
    cv::Mat row(1, 128, CV_32F);
    for (int c = 0; c < 128; ++c) row.at<float>(c) = uniform(*rng) < 0.2f ? uniform(*rng) : 0.0f;
    prototypes.push_back(row / cv::norm(row));
  }
  return prototypes;
}

// `rows` RootSIFT byte rows drawn from the prototypes `shown`, each with noise of `noise` per
// component, as the model stores them.
cv::Mat Descriptors(const std::vector<cv::Mat>& prototypes, const std::vector<int>& shown, int rows,
                    float noise, std::mt19937* rng) {
  std::normal_distribution<float> gauss(0.0f, noise);
  cv::Mat bytes(rows, 128, CV_8U);
  for (int r = 0; r < rows; ++r) {
    cv::Mat row =
        prototypes[static_cast<size_t>(shown[static_cast<size_t>(r) % shown.size()])].clone();
    for (int c = 0; c < 128; ++c) row.at<float>(c) = std::max(0.0f, row.at<float>(c) + gauss(*rng));
    row *= kRootSiftScale / cv::norm(row);
    row.convertTo(bytes.row(r), CV_8U);
  }
  return bytes;
}

// Three rooms, each showing its own 6 of 18 things; the walk saw each room twice.
struct Walk {
  std::vector<cv::Mat> prototypes;
  std::vector<std::vector<int>> rooms;
  std::vector<cv::Mat> images;  // room r's views at 2r and 2r + 1
};
Walk MakeWalk(std::mt19937* rng) {
  Walk walk;
  walk.prototypes = Prototypes(18, rng);
  walk.rooms = {{0, 1, 2, 3, 4, 5}, {6, 7, 8, 9, 10, 11}, {12, 13, 14, 15, 16, 17}};
  for (const std::vector<int>& room : walk.rooms) {
    for (int view = 0; view < 2; ++view) {
      walk.images.push_back(Descriptors(walk.prototypes, room, 120, 0.01f, rng));
    }
  }
  return walk;
}

VladOptions SmallCodebook() {
  VladOptions options;
  options.centres = 16;
  options.sample_step = 2;
  return options;
}

TEST(VladIndex, RanksTheViewsOfTheRoomAPhotoShowsFirst) {
  std::mt19937 rng(5);
  const Walk walk = MakeWalk(&rng);
  VladIndex index = VladIndex::Train(walk.images, SmallCodebook());
  for (size_t i = 0; i < walk.images.size(); ++i) {
    index.Add(static_cast<int64_t>(i), walk.images[i]);
  }
  EXPECT_EQ(index.size(), 6u);
  EXPECT_EQ(index.dimension(), 16 * 128);
  // A photo of room 1 from elsewhere: half of its things, noisier than the walk's views.
  const cv::Mat photo = Descriptors(walk.prototypes, {6, 8, 9}, 40, 0.02f, &rng);
  const std::vector<PlaceCandidate> ranked = index.Rank(photo, 4);
  ASSERT_EQ(ranked.size(), 4u);
  EXPECT_TRUE((ranked[0].id == 2 && ranked[1].id == 3) || (ranked[0].id == 3 && ranked[1].id == 2))
      << ranked[0].id << " " << ranked[1].id;
  EXPECT_GT(ranked[1].score, 1.2 * ranked[2].score);  // the other rooms score clearly lower
  EXPECT_LE(ranked[0].score, 1.0 + 1e-6);
  // Asking for more than it holds returns what it holds.
  EXPECT_EQ(index.Rank(photo, 100).size(), 6u);
  EXPECT_TRUE(index.Rank(photo, 0).empty());
}

TEST(VladIndex, VectorsAreUnitLengthAndAnImageWithoutDescriptorsIsNeverRanked) {
  std::mt19937 rng(6);
  const Walk walk = MakeWalk(&rng);
  VladIndex index = VladIndex::Train(walk.images, SmallCodebook());
  const cv::Mat vector = index.Encode(walk.images[0]);
  EXPECT_EQ(vector.cols, index.dimension());
  EXPECT_NEAR(cv::norm(vector), 1.0, 1e-5);
  EXPECT_EQ(cv::norm(index.Encode(cv::Mat())), 0.0);
  index.Add(10, walk.images[0]);
  index.Add(11, cv::Mat());  // a keyframe that found no RootSIFT
  const std::vector<PlaceCandidate> ranked = index.Rank(walk.images[1], 10);
  ASSERT_EQ(ranked.size(), 1u);
  EXPECT_EQ(ranked[0].id, 10);
  EXPECT_TRUE(index.Rank(cv::Mat(), 10).empty());  // a photo without RootSIFT finds nothing
}

TEST(VladIndex, TheCodebookDependsOnTheDescriptorsAloneAndLeavesTheCallersGeneratorAsItWas) {
  std::mt19937 rng(7);
  const Walk walk = MakeWalk(&rng);
  cv::theRNG().state = 12345;
  const VladIndex first = VladIndex::Train(walk.images, SmallCodebook());
  EXPECT_EQ(cv::theRNG().state, 12345u);
  cv::theRNG().state = 999;
  const VladIndex second = VladIndex::Train(walk.images, SmallCodebook());
  EXPECT_EQ(cv::norm(first.Encode(walk.images[3]), second.Encode(walk.images[3]), cv::NORM_INF),
            0.0);
  VladOptions other_seed = SmallCodebook();
  other_seed.seed = 2;
  EXPECT_GT(
      cv::norm(first.Encode(walk.images[3]),
               VladIndex::Train(walk.images, other_seed).Encode(walk.images[3]), cv::NORM_INF),
      0.0);
}

TEST(VladIndex, RefusesWhatItCannotIndex) {
  std::mt19937 rng(8);
  const Walk walk = MakeWalk(&rng);
  EXPECT_THROW(VladIndex().Encode(walk.images[0]), InvalidArgument);
  const cv::Mat orb(10, 32, CV_8U, cv::Scalar(1));
  EXPECT_THROW(VladIndex::Train({orb}, SmallCodebook()), InvalidArgument);
  EXPECT_EQ(VladIndex::SampledRows(walk.images, SmallCodebook()), 6u * 60u);  // every 2nd of 120
  VladOptions many = SmallCodebook();
  many.centres = 1000;  // more centres than sampled descriptors
  EXPECT_THROW(VladIndex::Train(walk.images, many), InvalidArgument);
  VladOptions bad = SmallCodebook();
  bad.kmeans_iterations = 0;
  std::string error;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("kmeans_iterations"), std::string::npos) << error;
  EXPECT_THROW(VladIndex::Train(walk.images, bad), InvalidArgument);
  VladIndex index = VladIndex::Train(walk.images, SmallCodebook());
  EXPECT_THROW(index.Encode(orb), InvalidArgument);
  index.Add(1, walk.images[0]);
  EXPECT_THROW(index.Add(1, walk.images[1]), InvalidArgument);
}

}  // namespace
}  // namespace sightmap::slam
