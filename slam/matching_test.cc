#include "slam/matching.h"

#include <algorithm>
#include <climits>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>

namespace sightmap::slam {
namespace {

// Random 256-bit descriptors; every third query is a copy of a reference with a few bits flipped,
// so that the ratio test and the cross check both keep and refuse matches.
void PlantedDescriptors(int num_query, int num_reference, cv::Mat* query, cv::Mat* reference) {
  cv::RNG rng(7);
  reference->create(num_reference, 32, CV_8U);
  rng.fill(*reference, cv::RNG::UNIFORM, 0, 256);
  query->create(num_query, 32, CV_8U);
  rng.fill(*query, cv::RNG::UNIFORM, 0, 256);
  for (int q = 0; q < num_query; q += 3) {
    const int r = (q * 7) % num_reference;
    reference->row(r).copyTo(query->row(q));
    const int flips = q % 40;
    for (int f = 0; f < flips; ++f) {
      const int bit = rng.uniform(0, 256);
      query->at<uint8_t>(q, bit / 8) ^= static_cast<uint8_t>(1u << (bit % 8));
    }
  }
}

// What the matcher did before: cv::BFMatcher's two nearest, its backward match as cross check.
std::vector<cv::DMatch> ReferenceMatches(const cv::Mat& query, const cv::Mat& reference,
                                         const MatchOptions& options) {
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, reference, knn, 2);
  std::vector<cv::DMatch> backward;
  matcher.match(reference, query, backward);
  std::vector<cv::DMatch> matches;
  for (const std::vector<cv::DMatch>& pair : knn) {
    if (pair[0].distance >= options.ratio * pair[1].distance) continue;
    if (options.mutual &&
        backward[static_cast<size_t>(pair[0].trainIdx)].trainIdx != pair[0].queryIdx) {
      continue;
    }
    matches.push_back(pair[0]);
  }
  return matches;
}

void ExpectSameMatches(const std::vector<cv::DMatch>& actual,
                       const std::vector<cv::DMatch>& expected) {
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < actual.size(); ++i) {
    EXPECT_EQ(actual[i].queryIdx, expected[i].queryIdx) << i;
    EXPECT_EQ(actual[i].trainIdx, expected[i].trainIdx) << i;
    EXPECT_EQ(actual[i].distance, expected[i].distance) << i;
  }
}

TEST(Matching, BinaryMatchesAreOpenCvsBruteForceMatches) {
  cv::Mat query, reference;
  PlantedDescriptors(600, 500, &query, &reference);
  for (const bool mutual : {true, false}) {
    for (const double ratio : {0.8, 0.9, 1.0}) {
      MatchOptions options;
      options.mutual = mutual;
      options.ratio = ratio;
      const std::vector<cv::DMatch> expected = ReferenceMatches(query, reference, options);
      SCOPED_TRACE(testing::Message() << "mutual " << mutual << ", ratio " << ratio);
      ExpectSameMatches(MatchDescriptors(query, reference, options), expected);
      // The planted copies (200 queries, up to 39 bits flipped) pass; with a ratio below 1 few
      // random queries do.
      EXPECT_GT(expected.size(), 150u);
      if (ratio < 1.0) {
        EXPECT_LT(expected.size(), 400u);
      }
    }
  }
}

TEST(Matching, KNearestAreOpenCvsKnnMatch) {
  cv::Mat query, reference;
  PlantedDescriptors(300, 400, &query, &reference);
  // Duplicated references give equal distances; their order must be OpenCV's too.
  reference.row(5).copyTo(reference.row(6));
  reference.row(5).copyTo(reference.row(300));
  reference.row(5).copyTo(query.row(1));
  for (const int k : {1, 2, 4}) {
    std::vector<std::vector<cv::DMatch>> expected;
    cv::BFMatcher(cv::NORM_HAMMING).knnMatch(query, reference, expected, k);
    const std::vector<std::vector<cv::DMatch>> actual = KNearestBinary(query, reference, k);
    ASSERT_EQ(actual.size(), expected.size());
    for (size_t q = 0; q < actual.size(); ++q) {
      SCOPED_TRACE(testing::Message() << "k " << k << ", query " << q);
      ExpectSameMatches(actual[q], expected[q]);
    }
  }
  const std::vector<std::vector<cv::DMatch>> four = KNearestBinary(query, reference, 4);
  EXPECT_EQ(four[1][0].trainIdx, 5);
  EXPECT_EQ(four[1][1].trainIdx, 6);
  EXPECT_EQ(four[1][2].trainIdx, 300);
  EXPECT_EQ(four[1][2].distance, 0.0f);
}

// Every kernel this CPU runs gives the portable kernel's lists, ties included, at reference
// counts that fill the vector kernels' blocks (of four and eight) and that do not (their padding
// is never a neighbour, even for a query that matches the padding's bits exactly).
TEST(Matching, KNearestKernelsAgree) {
  int compared = 0;
  for (const MatchKernel kernel : {MatchKernel::kAvx512, MatchKernel::kAvx2}) {
    if (!HasKernel(kernel)) continue;
    ++compared;
    for (const int rows : {1, 3, 4, 5, 7, 8, 9, 403}) {
      cv::Mat query, reference;
      PlantedDescriptors(120, rows, &query, &reference);
      query.row(0).setTo(cv::Scalar(255));  // all ones, as the padding
      reference.row(0).copyTo(reference.row(rows - 1));
      for (const int k : {1, 4}) {
        const auto fast = KNearestBinary(query, reference, k, kernel);
        const auto portable = KNearestBinary(query, reference, k, MatchKernel::kPortable);
        ASSERT_EQ(fast.size(), portable.size());
        for (size_t q = 0; q < fast.size(); ++q) {
          SCOPED_TRACE(testing::Message() << "kernel " << static_cast<int>(kernel) << ", " << rows
                                          << " references, k " << k << ", query " << q);
          ExpectSameMatches(fast[q], portable[q]);
          for (const cv::DMatch& match : fast[q]) EXPECT_LT(match.trainIdx, rows);
        }
      }
    }
  }
  if (compared == 0) GTEST_SKIP() << "this CPU has neither AVX2 nor AVX-512: one kernel only";
}

TEST(Matching, KNearestRefusesAKernelTheCpuLacks) {
  cv::Mat query, reference;
  PlantedDescriptors(3, 5, &query, &reference);
  for (const MatchKernel kernel : {MatchKernel::kAvx512, MatchKernel::kAvx2}) {
    if (HasKernel(kernel)) continue;
    EXPECT_THROW(KNearestBinary(query, reference, 2, kernel), std::exception);
  }
  EXPECT_TRUE(HasKernel(MatchKernel::kPortable));
  EXPECT_TRUE(HasKernel(MatchKernel::kFastest));
  EXPECT_TRUE(HasKernel(FastestKernel()));
  EXPECT_NE(FastestKernel(), MatchKernel::kFastest);
  EXPECT_EQ(KernelName(MatchKernel::kAvx2), "avx2");
  EXPECT_EQ(KernelName(MatchKernel::kPortable), "portable");
}

TEST(Matching, KNearestOfFewerReferencesThanKListsThemAll) {
  cv::Mat query, reference;
  PlantedDescriptors(3, 2, &query, &reference);
  const std::vector<std::vector<cv::DMatch>> knn = KNearestBinary(query, reference, 4);
  ASSERT_EQ(knn.size(), 3u);
  for (const std::vector<cv::DMatch>& neighbours : knn) {
    ASSERT_EQ(neighbours.size(), 2u);
    EXPECT_LE(neighbours[0].distance, neighbours[1].distance);
  }
  EXPECT_TRUE(KNearestBinary(query, cv::Mat(0, 32, CV_8U), 4)[0].empty());
}

TEST(Matching, EqualDistancesKeepTheFirstReferenceAndFailTheRatioTest) {
  cv::Mat reference(3, 32, CV_8U, cv::Scalar(0));
  reference.row(2).setTo(cv::Scalar(255));
  cv::Mat query(1, 32, CV_8U, cv::Scalar(0));
  const BinaryNeighbours neighbours = FindBinaryNeighbours(query, reference);
  EXPECT_EQ(neighbours.best[0], 0);  // rows 0 and 1 are both at distance 0
  EXPECT_EQ(neighbours.best_distance[0], 0);
  EXPECT_EQ(neighbours.second_distance[0], 0);
  EXPECT_EQ(neighbours.best_query[0], 0);
  EXPECT_EQ(neighbours.best_query[2], 0);
  EXPECT_TRUE(MatchDescriptors(query, reference).empty());
}

TEST(Matching, OneReferenceHasNoSecondNeighbour) {
  cv::Mat reference(1, 32, CV_8U, cv::Scalar(0));
  cv::Mat query(2, 32, CV_8U, cv::Scalar(1));
  const BinaryNeighbours neighbours = FindBinaryNeighbours(query, reference);
  EXPECT_EQ(neighbours.best[1], 0);
  EXPECT_EQ(neighbours.best_distance[1], 32);
  EXPECT_EQ(neighbours.second_distance[1], INT_MAX);
  EXPECT_EQ(neighbours.best_query[0], 0);
  // The ratio test needs a second neighbour: nothing is matched against one reference.
  EXPECT_TRUE(MatchDescriptors(query, reference).empty());
  // No references: every query has none; no queries: every reference has none.
  const BinaryNeighbours none = FindBinaryNeighbours(query, cv::Mat(0, 32, CV_8U));
  EXPECT_EQ(none.best, std::vector<int>({-1, -1}));
  EXPECT_TRUE(none.best_query.empty());
  EXPECT_EQ(FindBinaryNeighbours(cv::Mat(), reference).best_query, std::vector<int>({-1}));
}

TEST(Matching, FloatDescriptorsStillMatch) {
  cv::Mat reference(4, 8, CV_32F);
  cv::randu(reference, 0.0, 1.0);
  cv::Mat query = reference.row(2).clone();
  query.at<float>(0, 0) += 0.01f;
  const std::vector<cv::DMatch> matches = MatchDescriptors(query, reference);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].trainIdx, 2);
}

TEST(Matching, RefusesDescriptorsOfDifferentLengths) {
  const cv::Mat query(2, 32, CV_8U, cv::Scalar(0));
  const cv::Mat reference(2, 16, CV_8U, cv::Scalar(0));
  EXPECT_ANY_THROW(MatchDescriptors(query, reference));
}

// Random 128-byte rows (RootSIFT-like); query q is reference (q * 7) % n with small noise.
void PlantedByteRows(int num_query, int num_reference, cv::Mat* query, cv::Mat* reference) {
  cv::RNG rng(11);
  reference->create(num_reference, 128, CV_8U);
  rng.fill(*reference, cv::RNG::UNIFORM, 0, 64);
  query->create(num_query, 128, CV_8U);
  for (int q = 0; q < num_query; ++q) {
    const int r = (q * 7) % num_reference;
    for (int c = 0; c < 128; ++c) {
      query->at<uint8_t>(q, c) =
          cv::saturate_cast<uint8_t>(reference->at<uint8_t>(r, c) + rng.uniform(-3, 4));
    }
  }
}

// OpenCV's brute-force k nearest of byte rows compared as floats.
std::vector<std::vector<cv::DMatch>> OpenCvEuclideanKnn(const cv::Mat& query,
                                                        const cv::Mat& reference, int k) {
  cv::Mat query_f;
  cv::Mat reference_f;
  query.convertTo(query_f, CV_32F);
  reference.convertTo(reference_f, CV_32F);
  std::vector<std::vector<cv::DMatch>> expected;
  cv::BFMatcher(cv::NORM_L2).knnMatch(query_f, reference_f, expected, k);
  return expected;
}

// Byte rows are compared exactly by every kernel this CPU runs: OpenCV's lists, ties included
// (duplicated references), distances to the last bit, at reference counts that fill the AVX2
// kernel's blocks of four and that do not, and at a width it does not take (40 bytes).
TEST(Matching, EuclideanKNearestOfBytesIsOpenCvsKnnMatch) {
  for (const MatchKernel kernel :
       {MatchKernel::kFastest, MatchKernel::kAvx2, MatchKernel::kPortable}) {
    if (!HasKernel(kernel)) continue;
    for (const int rows : {1, 3, 4, 5, 301}) {
      for (const int cols : {128, 40}) {
        cv::Mat query;
        cv::Mat reference;
        PlantedByteRows(60, rows, &query, &reference);
        query = query.colRange(0, cols).clone();
        reference = reference.colRange(0, cols).clone();
        reference.row(0).copyTo(reference.row(rows - 1));
        for (const int k : {1, 3}) {
          const auto knn = KNearestEuclidean(query, reference, k, kernel);
          const auto expected = OpenCvEuclideanKnn(query, reference, k);
          ASSERT_EQ(knn.size(), expected.size());
          for (size_t q = 0; q < knn.size(); ++q) {
            SCOPED_TRACE(testing::Message() << "kernel " << static_cast<int>(kernel) << ", " << rows
                                            << " x " << cols << ", k " << k << ", query " << q);
            ExpectSameMatches(knn[q], expected[q]);
          }
        }
      }
    }
  }
}

TEST(Matching, EuclideanKNearestOfBytesFindsThePlantedNeighbourAtAnySize) {
  cv::Mat query;
  cv::Mat reference;
  PlantedByteRows(1000, 6000, &query, &reference);
  ASSERT_GT(1000.0 * 6000.0, kExactEuclideanPairs);  // float rows would go to the kd-trees
  const auto knn = KNearestEuclidean(query, reference, 2);
  ASSERT_EQ(knn.size(), 1000u);
  for (size_t q = 0; q < knn.size(); ++q) {
    ASSERT_EQ(knn[q].size(), 2u);
    EXPECT_EQ(knn[q][0].trainIdx, static_cast<int>((q * 7) % 6000)) << q;
    EXPECT_LE(knn[q][0].distance, knn[q][1].distance);
  }
}

// Float rows above kExactEuclideanPairs are answered by kd-trees: nearly every planted neighbour
// is found, with its true distance, and the same input gives the same answer.
TEST(Matching, EuclideanKNearestOfManyFloatPairsFindsThePlantedNeighbourTheSameWayTwice) {
  cv::Mat query_bytes;
  cv::Mat reference_bytes;
  PlantedByteRows(1000, 6000, &query_bytes, &reference_bytes);
  cv::Mat query;
  cv::Mat reference;
  query_bytes.convertTo(query, CV_32F);
  reference_bytes.convertTo(reference, CV_32F);
  ASSERT_GT(1000.0 * 6000.0, kExactEuclideanPairs);
  const auto knn = KNearestEuclidean(query, reference, 2);
  const auto again = KNearestEuclidean(query, reference, 2);
  ASSERT_EQ(knn.size(), 1000u);
  int found = 0;
  for (size_t q = 0; q < knn.size(); ++q) {
    ASSERT_EQ(knn[q].size(), 2u);
    ASSERT_EQ(again[q].size(), 2u);
    EXPECT_EQ(knn[q][0].trainIdx, again[q][0].trainIdx);
    EXPECT_LE(knn[q][0].distance, knn[q][1].distance);
    const int r = knn[q][0].trainIdx;
    EXPECT_NEAR(knn[q][0].distance, cv::norm(query.row(static_cast<int>(q)), reference.row(r)),
                1e-2);
    if (r == static_cast<int>((q * 7) % 6000)) ++found;
  }
  EXPECT_GE(found, 950);
}

TEST(Matching, EuclideanKNearestOfNothingIsEmptyAndOfMismatchedRowsThrows) {
  cv::Mat query;
  cv::Mat reference;
  PlantedByteRows(5, 10, &query, &reference);
  const auto none = KNearestEuclidean(query, cv::Mat(0, 128, CV_8U), 2);
  ASSERT_EQ(none.size(), 5u);
  for (const auto& neighbours : none) EXPECT_TRUE(neighbours.empty());
  EXPECT_THROW(KNearestEuclidean(query, cv::Mat(4, 64, CV_8U, cv::Scalar(1)), 2), std::exception);
  EXPECT_THROW(KNearestEuclidean(query, reference, 0), std::exception);
}

}  // namespace
}  // namespace sightmap::slam
