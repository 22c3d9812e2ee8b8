#include "slam/vote_index.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

#include "core/check.h"
#include "slam/vocabulary.h"

namespace sightmap::slam {
namespace {

cv::Mat RandomDescriptors(int rows, std::mt19937* rng) {
  std::uniform_int_distribution<int> byte(0, 255);
  cv::Mat descriptors(rows, 32, CV_8U);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 32; ++c) descriptors.at<uint8_t>(r, c) = static_cast<uint8_t>(byte(*rng));
  }
  return descriptors;
}

// The descriptors with `bits` distinct bits of each row flipped.
cv::Mat Flipped(const cv::Mat& descriptors, int bits, std::mt19937* rng) {
  cv::Mat flipped = descriptors.clone();
  for (int r = 0; r < flipped.rows; ++r) {
    std::vector<int> order(256);
    for (int b = 0; b < 256; ++b) order[static_cast<size_t>(b)] = b;
    std::shuffle(order.begin(), order.end(), *rng);
    for (int b = 0; b < bits; ++b) {
      const int bit = order[static_cast<size_t>(b)];
      flipped.at<uint8_t>(r, bit / 8) ^= static_cast<uint8_t>(1u << (bit % 8));
    }
  }
  return flipped;
}

std::vector<int> SameWord(int rows, int word = 7) { return std::vector<int>(rows, word); }

TEST(VoteIndex, RowsWithinReachVoteOnceForEachKeyframe) {
  std::mt19937 rng(3);
  const cv::Mat query = RandomDescriptors(10, &rng);
  VoteIndex index(30);
  // Keyframe 5 holds all ten rows 20 bits away, keyframe 6 the first four 30 bits away (the
  // limit) and the rest 31 away, keyframe 7 every row twice (a repeated texture): one vote each.
  index.Add(5, Flipped(query, 20, &rng), SameWord(10));
  cv::Mat six = Flipped(query, 31, &rng);
  Flipped(query.rowRange(0, 4), 30, &rng).copyTo(six.rowRange(0, 4));
  index.Add(6, six, SameWord(10));
  cv::Mat twice;
  cv::vconcat(Flipped(query, 5, &rng), Flipped(query, 6, &rng), twice);
  index.Add(7, twice, SameWord(20));
  index.Add(8, RandomDescriptors(10, &rng), SameWord(10));  // about 128 bits from each row

  const std::vector<int64_t> all = {8, 7, 6, 5};
  const std::vector<PlaceCandidate> ranked = index.Rank(query, SameWord(10), all, 5);
  ASSERT_EQ(ranked.size(), 3u);
  EXPECT_EQ(ranked[0].id, 5);  // ties (10 votes) by smaller id
  EXPECT_DOUBLE_EQ(ranked[0].score, 1.0);
  EXPECT_EQ(ranked[1].id, 7);
  EXPECT_DOUBLE_EQ(ranked[1].score, 1.0);
  EXPECT_EQ(ranked[2].id, 6);
  EXPECT_DOUBLE_EQ(ranked[2].score, 0.4);

  const std::vector<PlaceCandidate> best = index.Rank(query, SameWord(10), all, 1);
  ASSERT_EQ(best.size(), 1u);
  EXPECT_EQ(best[0].id, 5);
  // Only the shortlist is ranked.
  const std::vector<PlaceCandidate> listed = index.Rank(query, SameWord(10), {6, 8}, 5);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].id, 6);
}

TEST(VoteIndex, OnlyDescriptorsOfTheSameWordVote) {
  std::mt19937 rng(4);
  const cv::Mat query = RandomDescriptors(4, &rng);
  VoteIndex index(40);
  index.Add(1, query.clone(), {1, 2, 3, 4});
  index.Add(2, query.clone(), {1, 2, 9, 9});  // the same bits under other words for rows 2-3
  const std::vector<PlaceCandidate> ranked = index.Rank(query, {1, 2, 3, 4}, {1, 2}, 10);
  ASSERT_EQ(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].id, 1);
  EXPECT_DOUBLE_EQ(ranked[0].score, 1.0);
  EXPECT_EQ(ranked[1].id, 2);
  EXPECT_DOUBLE_EQ(ranked[1].score, 0.5);
  // A query of a word nobody holds finds nothing.
  EXPECT_TRUE(index.Rank(query, {5, 5, 5, 5}, {1, 2}, 10).empty());
}

TEST(VoteIndex, EmptyQueriesAndIndexesGiveNothing) {
  std::mt19937 rng(5);
  const cv::Mat query = RandomDescriptors(3, &rng);
  EXPECT_TRUE(VoteIndex().Rank(query, SameWord(3), {}, 5).empty());
  VoteIndex index;
  index.Add(1, query, SameWord(3));
  index.Add(2, cv::Mat(), {});  // a keyframe without features
  EXPECT_EQ(index.size(), 2u);
  EXPECT_TRUE(index.Rank(query, SameWord(3), {2}, 5).empty());
  EXPECT_TRUE(index.Rank(cv::Mat(), {}, {1, 2}, 5).empty());
  EXPECT_TRUE(index.Rank(query, SameWord(3), {1, 2}, 0).empty());
  EXPECT_EQ(index.Rank(query, SameWord(3), {1, 2}, 5).size(), 1u);
}

TEST(VoteIndex, BadInputThrowsInvalidArgument) {
  std::mt19937 rng(6);
  const cv::Mat descriptors = RandomDescriptors(3, &rng);
  EXPECT_THROW(VoteIndex(-1), InvalidArgument);
  EXPECT_THROW(VoteIndex(257), InvalidArgument);
  VoteIndex index;
  index.Add(1, descriptors, SameWord(3));
  EXPECT_THROW(index.Add(1, descriptors, SameWord(3)), InvalidArgument);  // duplicate id
  EXPECT_THROW(index.Add(2, descriptors, SameWord(2)), InvalidArgument);  // word count
  cv::Mat sift(3, 128, CV_8U, cv::Scalar(0));
  EXPECT_THROW(index.Add(3, sift, SameWord(3)), InvalidArgument);
  EXPECT_THROW(index.Rank(descriptors, SameWord(4), {1}, 5), InvalidArgument);
  EXPECT_THROW(index.Rank(descriptors, SameWord(3), {1, 9}, 5), InvalidArgument);  // unknown id
  EXPECT_FALSE(index.Contains(2));
  EXPECT_FALSE(index.Contains(3));
}

// The vocabulary's words with the index: an image of the same place, its descriptors seen again
// with noise, outranks images of other places.
TEST(VoteIndex, WithAVocabularyTheSamePlaceRanksFirst) {
  std::mt19937 rng(7);
  std::vector<cv::Mat> places;
  for (int p = 0; p < 6; ++p) places.push_back(RandomDescriptors(200, &rng));
  const Vocabulary vocabulary = Vocabulary::Train(places, [] {
    VocabularyOptions options;
    options.branching = 4;
    options.depth = 3;
    return options;
  }());
  VoteIndex index(30);
  for (int p = 0; p < 6; ++p) {
    std::vector<int> words;
    vocabulary.Transform(places[static_cast<size_t>(p)], &words);
    index.Add(p, places[static_cast<size_t>(p)], words);
  }
  for (int p = 0; p < 6; ++p) {
    const cv::Mat seen_again = Flipped(places[static_cast<size_t>(p)].rowRange(0, 100), 12, &rng);
    std::vector<int> words;
    vocabulary.Transform(seen_again, &words);
    const std::vector<PlaceCandidate> ranked = index.Rank(seen_again, words, {0, 1, 2, 3, 4, 5}, 3);
    ASSERT_FALSE(ranked.empty()) << "place " << p;
    EXPECT_EQ(ranked[0].id, p);
    // Noise moves some rows to a neighbouring word, where they find nothing; most stay.
    EXPECT_GT(ranked[0].score, 0.5) << "place " << p;
    if (ranked.size() > 1) {
      EXPECT_LT(ranked[1].score, 0.1) << "place " << p;
    }
  }
}

}  // namespace
}  // namespace sightmap::slam
