// Each stage of Locator::Locate alone, on hand-built keyframes, matches and verdicts.
#include "identify/locate_stages.h"

#include <cmath>
#include <functional>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "identify/view_agreement_testing.h"

namespace sightmap::identify {
namespace {

using testing::PoseAt;

LocatorKeyframe KeyframeAt(const Eigen::Vector3d& position, double yaw_deg, int points = 1) {
  LocatorKeyframe keyframe;
  keyframe.world_from_cam = PoseAt(position, yaw_deg);
  keyframe.view_direction = keyframe.world_from_cam.linear().col(2);
  for (int i = 0; i < points; ++i) keyframe.world_points.emplace_back(0.0f, 0.0f, 1.0f);
  keyframe.descriptors = cv::Mat::zeros(points, 32, CV_8U);
  return keyframe;
}

cv::Mat RandomDescriptors(int rows, std::mt19937* rng) {
  cv::Mat descriptors(rows, 32, CV_8U);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 32; ++c) descriptors.at<uint8_t>(r, c) = static_cast<uint8_t>(byte(*rng));
  }
  return descriptors;
}

// `bits` of the descriptor flipped, at distinct positions.
cv::Mat Flipped(const cv::Mat& row, int bits) {
  cv::Mat flipped = row.clone();
  for (int b = 0; b < bits; ++b)
    flipped.at<uint8_t>(0, (b * 7) % 32) ^= static_cast<uint8_t>(1u << (b % 8));
  return flipped;
}

TEST(FindNeighboursTest, NearestFirstWithinRadiusAndAngleOnlyKeyframesWithPoints) {
  LocatorOptions options;
  options.neighbour_radius_m = 1.0;
  options.neighbour_max_angle_deg = 45.0;
  options.max_neighbours = 2;
  std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0, 0, 0}, 0),       // 0
      KeyframeAt({0.6, 0, 0}, 10),    // 1: near, similar view
      KeyframeAt({0.3, 0, 0}, 30),    // 2: nearer, similar view
      KeyframeAt({0.2, 0, 0}, 90),    // 3: near, looking elsewhere
      KeyframeAt({1.5, 0, 0}, 0),     // 4: too far
      KeyframeAt({0.1, 0, 0}, 0, 0),  // 5: nearest, but no 3D points to match
      KeyframeAt({0.9, 0, 0}, 0),     // 6: near, but beyond max_neighbours
  };
  FindNeighbours(options, &keyframes);
  EXPECT_EQ(keyframes[0].neighbours, (std::vector<size_t>{2, 1}));
  EXPECT_TRUE(keyframes[3].neighbours.empty());
  // A keyframe without points still has neighbours to match with.
  EXPECT_EQ(keyframes[5].neighbours, (std::vector<size_t>{0, 2}));
}

TEST(RetrieveCandidatesTest, WithoutAVocabularyEveryKeyframeWithPointsIsACandidate) {
  LocatorOptions options;
  const std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0, 0, 0}, 0), KeyframeAt({1, 0, 0}, 0, 0), KeyframeAt({2, 0, 0}, 0)};
  std::mt19937 rng(1);
  const std::vector<slam::PlaceCandidate> candidates = RetrieveCandidates(
      RandomDescriptors(50, &rng), LocatorOptions::Retrieval::kVotes, 20, slam::Vocabulary(),
      slam::PlaceIndex(), slam::VoteIndex(), keyframes, options);
  ASSERT_EQ(candidates.size(), 2u);
  EXPECT_EQ(candidates[0].id, 0);
  EXPECT_EQ(candidates[1].id, 2);
}

// Votes re-rank the bag of words' shortlist; bag of words alone keeps its order.
TEST(RetrieveCandidatesTest, VotesReRankTheBagOfWordsShortlist) {
  LocatorOptions options;
  options.vote_shortlist = 3;
  const std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0, 0, 0}, 0), KeyframeAt({1, 0, 0}, 0), KeyframeAt({2, 0, 0}, 0)};
  std::mt19937 rng(2);
  std::vector<cv::Mat> images;
  for (int i = 0; i < 3; ++i) images.push_back(RandomDescriptors(100, &rng));
  const slam::Vocabulary vocabulary = slam::Vocabulary::Train(images, [] {
    slam::VocabularyOptions v;
    v.branching = 8;
    v.depth = 3;
    return v;
  }());
  // The query: image 1 with every descriptor 40 bits off (beyond vote_max_hamming, though often
  // under the same word) and image 2's first 30 descriptors as they are. Keyframe 1 holds image 1
  // and wins by bag of words; keyframe 2 holds image 2 and wins by votes.
  cv::Mat query = images[1].clone();
  for (int r = 0; r < query.rows; ++r) {
    for (int bit = 0; bit < 40; ++bit) {
      query.at<uint8_t>(r, bit / 8) ^= static_cast<uint8_t>(1u << (bit % 8));
    }
  }
  cv::vconcat(query, images[2].rowRange(0, 30), query);
  slam::VoteIndex votes(options.vote_max_hamming);
  slam::PlaceIndex index;
  for (int i = 0; i < 3; ++i) {
    std::vector<int> words;
    index.Add(i, vocabulary.Transform(images[static_cast<size_t>(i)], &words));
    votes.Add(i, images[static_cast<size_t>(i)], words);
  }
  // One candidate, fewer than the keyframes: ranked, not all taken.
  const auto by_words = RetrieveCandidates(query, LocatorOptions::Retrieval::kBagOfWords, 1,
                                           vocabulary, index, votes, keyframes, options);
  ASSERT_EQ(by_words.size(), 1u);
  EXPECT_EQ(by_words[0].id, 1);
  const auto by_votes = RetrieveCandidates(query, LocatorOptions::Retrieval::kVotes, 1, vocabulary,
                                           index, votes, keyframes, options);
  ASSERT_EQ(by_votes.size(), 1u);
  EXPECT_EQ(by_votes[0].id, 2);
  EXPECT_DOUBLE_EQ(by_votes[0].score, 30.0 / 130.0);
}

TEST(MergeCandidatesTest, TheFirstListsCandidatesComeFirstAndEachKeyframeOnce) {
  const std::vector<slam::PlaceCandidate> vlad = {{7, 0.3}, {2, 0.2}, {7, 0.1}};
  const std::vector<slam::PlaceCandidate> orb = {{2, 0.9}, {5, 0.8}, {1, 0.7}};
  const std::vector<slam::PlaceCandidate> merged = MergeCandidates(vlad, orb);
  ASSERT_EQ(merged.size(), 4u);
  EXPECT_EQ(merged[0].id, 7);
  EXPECT_EQ(merged[1].id, 2);
  EXPECT_DOUBLE_EQ(merged[1].score, 0.2);  // the first list's entry, not the later duplicate
  EXPECT_EQ(merged[2].id, 5);
  EXPECT_EQ(merged[3].id, 1);
  EXPECT_EQ(MergeCandidates({}, orb).size(), 3u);
  EXPECT_TRUE(MergeCandidates({}, {}).empty());
}

TEST(PutKeyframesFirstTest, TheGivenKeyframesComeFirstRankedOnesInRetrievalsOrder) {
  std::vector<LocatorKeyframe> keyframes;
  for (int slot = 0; slot < 6; ++slot) {
    keyframes.push_back(KeyframeAt({slot * 1.0, 0, 0}, 0));
    keyframes.back().id = KeyframeId(100 + slot);
  }
  // Slot 1 is a view rendered from keyframe 105 (slot 5): it carries that id but is not it.
  keyframes[1].id = KeyframeId(105);
  keyframes[1].synthetic_view = SyntheticViewId(1);
  const std::vector<slam::PlaceCandidate> retrieved = {{0, 0.9}, {3, 0.8}, {1, 0.7}, {2, 0.6}};
  // Keyframes 104 and 105 were not retrieved; 102 (slot 2) was, last; 999 is no keyframe.
  const std::vector<slam::PlaceCandidate> put = PutKeyframesFirst(
      retrieved,
      {KeyframeId(104), KeyframeId(999), KeyframeId(102), KeyframeId(105), KeyframeId(104)},
      keyframes);
  std::vector<int64_t> slots;
  for (const slam::PlaceCandidate& c : put) slots.push_back(c.id);
  // 2 (ranked), then 4 and 5 (unranked, in the order given), then the rest as retrieved.
  EXPECT_EQ(slots, (std::vector<int64_t>{2, 4, 5, 0, 3, 1}));
  EXPECT_DOUBLE_EQ(put[0].score, 0.6);
  EXPECT_DOUBLE_EQ(put[1].score, 0.0);
  std::vector<int64_t> unchanged;
  for (const slam::PlaceCandidate& c : PutKeyframesFirst(retrieved, {}, keyframes)) {
    unchanged.push_back(c.id);
  }
  EXPECT_EQ(unchanged, (std::vector<int64_t>{0, 3, 1, 2}));
}

TEST(GroupPlacesTest, NearbySimilarViewsShareAPlaceWithTheirNeighboursAtMostMaxPlaces) {
  LocatorOptions options;
  options.place_radius_m = 2.0;
  options.place_max_angle_deg = 60.0;
  options.max_places = 2;
  std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0, 0, 0}, 0),    // 0: best candidate
      KeyframeAt({5, 0, 0}, 0),    // 1: another part of the building
      KeyframeAt({1, 0, 0}, 40),   // 2: joins 0's place
      KeyframeAt({0, 0, 0}, 180),  // 3: same spot, opposite view: a third place, over the cap
      KeyframeAt({0.5, 0, 0}, 0),  // 4: 0's neighbour, never retrieved
  };
  keyframes[0].neighbours = {4};
  const std::vector<slam::PlaceCandidate> candidates = {{0, 0.9}, {1, 0.8}, {2, 0.7}, {3, 0.6}};
  const std::vector<Place> places =
      GroupPlaces(candidates, candidates.size(), options.max_places, keyframes, options);
  ASSERT_EQ(places.size(), 2u);
  EXPECT_EQ(places[0].head, 0u);
  EXPECT_EQ(places[0].slots, (std::vector<size_t>{0, 4, 2}));
  EXPECT_EQ(places[1].head, 1u);
  EXPECT_EQ(places[1].slots, (std::vector<size_t>{1}));

  options.max_places = 3;
  EXPECT_EQ(
      GroupPlaces(candidates, candidates.size(), options.max_places, keyframes, options).size(),
      3u);
  // A candidate that is not a keyframe slot is a programming error, not a photo's fault.
  EXPECT_THROW(GroupPlaces({{7, 0.5}}, 1, options.max_places, keyframes, options), Error);
}

// Reserve candidates (from reserve_from on) make places of their own after the first ones' and
// join only those: a first place does not grow with keyframes retrieved after it.
TEST(GroupPlacesTest, ReserveCandidatesOnlyMakePlacesOfTheirOwn) {
  LocatorOptions options;
  options.place_radius_m = 2.0;
  options.place_max_angle_deg = 60.0;
  options.max_places = 3;
  const std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0, 0, 0}, 0),    // 0: first candidate
      KeyframeAt({1, 0, 0}, 20),   // 1: reserve, sees 0's place: skipped
      KeyframeAt({9, 0, 0}, 0),    // 2: reserve, elsewhere: a place of its own
      KeyframeAt({9.5, 0, 0}, 0),  // 3: reserve, joins 2's place
      KeyframeAt({20, 0, 0}, 0),   // 4: reserve, a third place
      KeyframeAt({30, 0, 0}, 0),   // 5: reserve, over the cap
  };
  const std::vector<slam::PlaceCandidate> candidates = {{0, 0.9}, {1, 0.8}, {2, 0.7},
                                                        {3, 0.6}, {4, 0.5}, {5, 0.4}};
  const std::vector<Place> places =
      GroupPlaces(candidates, 1, options.max_places, keyframes, options);
  ASSERT_EQ(places.size(), 3u);
  EXPECT_EQ(places[0].slots, (std::vector<size_t>{0}));
  EXPECT_EQ(places[1].slots, (std::vector<size_t>{2, 3}));
  EXPECT_EQ(places[2].slots, (std::vector<size_t>{4}));
  // The same candidates all first: 1 joins 0's place.
  const std::vector<Place> all_first =
      GroupPlaces(candidates, candidates.size(), options.max_places, keyframes, options);
  ASSERT_EQ(all_first.size(), 3u);
  EXPECT_EQ(all_first[0].slots, (std::vector<size_t>{0, 1}));
  // Every candidate in reserve: grouped as first ones are.
  EXPECT_EQ(GroupPlaces(candidates, 0, options.max_places, keyframes, options)[0].slots,
            (std::vector<size_t>{0, 1}));
}

TEST(SharedPointShareTest, TheSameThingsSeenAgainShareTheirPointsACopyElsewhereDoesNot) {
  std::mt19937 rng(3);
  const LocatorOptions options;  // same_pose_m 0.5
  LocatorKeyframe desk = KeyframeAt({0, 0, 0}, 0, 0);
  desk.descriptors = RandomDescriptors(60, &rng);
  for (int i = 0; i < 60; ++i) desk.world_points.emplace_back(0.02f * i, 0.0f, 2.0f);
  // Another view of the same desk: its points within centimetres (SLAM's error).
  LocatorKeyframe again = desk;
  for (cv::Point3f& p : again.world_points) p.y += 0.03f;
  // The identical desk 2.2 m along.
  LocatorKeyframe twin = desk;
  for (cv::Point3f& p : twin.world_points) p.x += 2.2f;
  int matches = 0;
  EXPECT_DOUBLE_EQ(SharedPointShare(desk, again, options, &matches), 1.0);
  EXPECT_EQ(matches, 60);
  EXPECT_DOUBLE_EQ(SharedPointShare(desk, twin, options, &matches), 0.0);
  EXPECT_EQ(matches, 60);
  // Nothing in common: no matches, no share.
  LocatorKeyframe other = KeyframeAt({9, 0, 0}, 0, 0);
  other.descriptors = RandomDescriptors(60, &rng);
  other.world_points = desk.world_points;
  EXPECT_DOUBLE_EQ(SharedPointShare(desk, other, options, &matches), 0.0);
  EXPECT_EQ(matches, 0);
}

TEST(TwinPlacesTest, LookAlikesThatSeeOtherPointsBecomePlacesThoseOfTheWinnersOwnDoNot) {
  std::mt19937 rng(5);
  LocatorOptions options;
  options.twin_places = 2;
  const cv::Mat desk = RandomDescriptors(40, &rng);
  auto view = [&](const Eigen::Vector3d& at, const cv::Mat& descriptors, float shift_x) {
    LocatorKeyframe keyframe = KeyframeAt(at, 0, 0);
    keyframe.descriptors = descriptors.clone();
    for (int i = 0; i < descriptors.rows; ++i) {
      keyframe.world_points.emplace_back(shift_x + 0.02f * i, 0.0f, 2.0f);
    }
    return keyframe;
  };
  std::vector<LocatorKeyframe> keyframes = {
      view({0, 0, 0}, desk, 0.0f),    // 0: the winner's verified keyframe
      view({0.3, 0, 0}, desk, 0.0f),  // 1: the same desk again, not tried
      view({2.2, 0, 0}, desk, 2.2f),  // 2: the identical desk
      view({2.4, 0, 0}, desk, 2.2f),  // 3: the identical desk, next to 2: its place
      view({9, 0, 0}, desk, 9.0f),    // 4: a third copy, but already tried
      view({15, 0, 0}, desk, 15.0f),  // 5: a fourth copy, over the cap of two places
      view({20, 0, 0}, RandomDescriptors(40, &rng), 20.0f),  // 6: nothing alike
  };
  const std::vector<Place> tried = {Place{0, {0}}, Place{4, {4}}};
  const std::vector<slam::PlaceCandidate> look_alikes = {{0, 0.9}, {1, 0.5}, {2, 0.4}, {3, 0.35},
                                                         {4, 0.3}, {6, 0.2}, {5, 0.1}};
  const std::vector<Place> twins = TwinPlaces(look_alikes, 0, tried, keyframes, options);
  ASSERT_EQ(twins.size(), 2u);
  EXPECT_EQ(twins[0].head, 2u);
  EXPECT_EQ(twins[0].slots, (std::vector<size_t>{2, 3}));
  EXPECT_EQ(twins[1].head, 5u);

  options.twin_places = 0;
  EXPECT_TRUE(TwinPlaces(look_alikes, 0, tried, keyframes, options).empty());
  EXPECT_THROW(TwinPlaces(look_alikes, 9, tried, keyframes, options), Error);
}

TEST(TwinPlacesTest, ACopySeenFromAnotherAngleIsATwinWithFewerMatchesThanAPoseNeeds) {
  std::mt19937 rng(9);
  LocatorOptions options;  // min_inliers 25, twin_min_matches 15
  const cv::Mat desk = RandomDescriptors(40, &rng);
  LocatorKeyframe winner = KeyframeAt({0, 0, 0}, 0, 0);
  winner.descriptors = desk.clone();
  for (int i = 0; i < desk.rows; ++i) winner.world_points.emplace_back(0.02f * i, 0.0f, 2.0f);
  // The identical desk 2.2 m along, walked past at a turn: 18 of its 40 descriptors still match
  // the winner's keyframe's, the others changed with the view.
  LocatorKeyframe turned = KeyframeAt({2.2, 0, 0}, 35, 0);
  turned.descriptors = RandomDescriptors(40, &rng);
  desk.rowRange(0, 18).copyTo(turned.descriptors.rowRange(0, 18));
  for (int i = 0; i < desk.rows; ++i)
    turned.world_points.emplace_back(2.2f + 0.02f * i, 0.0f, 2.0f);
  const std::vector<LocatorKeyframe> keyframes = {winner, turned};
  int matches = 0;
  ASSERT_DOUBLE_EQ(SharedPointShare(winner, turned, options, &matches), 0.0);
  ASSERT_EQ(matches, 18);
  ASSERT_LT(matches, options.min_inliers);

  const std::vector<Place> tried = {Place{0, {0}}};
  const std::vector<slam::PlaceCandidate> look_alikes = {{0, 0.9}, {1, 0.4}};
  const std::vector<Place> twins = TwinPlaces(look_alikes, 0, tried, keyframes, options);
  ASSERT_EQ(twins.size(), 1u);
  EXPECT_EQ(twins[0].head, 1u);
  // Asking for as many matches as a pose needs loses it.
  options.twin_min_matches = options.min_inliers;
  EXPECT_TRUE(TwinPlaces(look_alikes, 0, tried, keyframes, options).empty());
  options.twin_min_matches = 0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("twin_min_matches"), std::string::npos) << error;
}

// A winner whose inliers are 60 things on a desk about (0, 0, 2), with their descriptors.
PlaceVerdict DeskWinner(std::mt19937* rng) {
  PlaceVerdict winner;
  winner.pose.valid = true;
  winner.inliers = 60;
  winner.inlier_descriptors = RandomDescriptors(60, rng);
  std::uniform_real_distribution<float> u(-0.6f, 0.6f);
  for (int i = 0; i < 60; ++i) winner.inlier_points.emplace_back(u(*rng), u(*rng), 2.0f + u(*rng));
  return winner;
}

// A keyframe holding `count` of the winner's things from `first` on (their descriptors with 6 bits
// flipped) moved by `offset` with up to `noise_m` of error each, and 40 unrelated features.
LocatorKeyframe CopyOf(const PlaceVerdict& winner, int first, int count,
                       const Eigen::Vector3f& offset, float noise_m, std::mt19937* rng) {
  LocatorKeyframe keyframe = KeyframeAt(offset.cast<double>(), 0, 0);
  keyframe.descriptors = cv::Mat(0, 32, CV_8U);
  std::uniform_real_distribution<float> noise(-noise_m, noise_m);
  for (int i = first; i < first + count; ++i) {
    keyframe.descriptors.push_back(Flipped(winner.inlier_descriptors.row(i), 6));
    const cv::Point3f& p = winner.inlier_points[static_cast<size_t>(i)];
    keyframe.world_points.emplace_back(p.x + offset.x() + noise(*rng),
                                       p.y + offset.y() + noise(*rng),
                                       p.z + offset.z() + noise(*rng));
  }
  keyframe.descriptors.push_back(RandomDescriptors(40, rng));
  std::uniform_real_distribution<float> anywhere(-10.0f, 10.0f);
  for (int i = 0; i < 40; ++i)
    keyframe.world_points.emplace_back(anywhere(*rng), anywhere(*rng), 1.0f);
  return keyframe;
}

TEST(CopyOffsetsTest, AThingRepeatedAlongTheBuildingVotesForItsOffsetMostSupportFirst) {
  std::mt19937 rng(21);
  LocatorOptions options;  // min_support 8, cluster 5 cm
  const PlaceVerdict winner = DeskWinner(&rng);
  const std::vector<LocatorKeyframe> keyframes = {
      // The winner's own desk seen again: its matches join the same points, no vote.
      CopyOf(winner, 0, 60, Eigen::Vector3f::Zero(), 0.01f, &rng),
      // The identical desk 2.2 m along, 20 of its things matched, mapped within 1 cm.
      CopyOf(winner, 10, 20, {0.0f, 2.2f, 0.0f}, 0.01f, &rng),
      // More of the same desk from another keyframe: the same inliers vote again.
      CopyOf(winner, 15, 10, {0.0f, 2.2f, 0.0f}, 0.01f, &rng),
      // A box like one on the desk, 5 m away: 12 things.
      CopyOf(winner, 40, 12, {5.0f, 0.0f, 0.0f}, 0.01f, &rng),
      // Four things like the desk's, scattered: no offset has enough voters.
      CopyOf(winner, 52, 1, {3.0f, -4.0f, 0.0f}, 0.0f, &rng),
      CopyOf(winner, 53, 1, {-6.0f, 1.0f, 0.0f}, 0.0f, &rng),
  };
  const std::vector<size_t> searched = {0, 1, 2, 3, 4, 5};
  const std::vector<CopyOffset> copies = CopyOffsets(winner, searched, keyframes, options);
  ASSERT_EQ(copies.size(), 2u);
  EXPECT_LT((copies[0].offset - Eigen::Vector3d(0, 2.2, 0)).norm(), 0.01);
  EXPECT_EQ(copies[0].support, 20);  // distinct inliers: the second keyframe's are among them
  EXPECT_LT((copies[1].offset - Eigen::Vector3d(5, 0, 0)).norm(), 0.01);
  EXPECT_EQ(copies[1].support, 12);

  // Support below the bar, only keyframes without the copies searched, one copy asked for, the
  // check off.
  options.copies.min_support = 13;
  EXPECT_EQ(CopyOffsets(winner, searched, keyframes, options).size(), 1u);
  options.copies.min_support = 8;
  EXPECT_TRUE(CopyOffsets(winner, {0, 4, 5}, keyframes, options).empty());
  EXPECT_THROW(CopyOffsets(winner, {0, 6}, keyframes, options), Error);
  options.copies.offsets = 1;
  ASSERT_EQ(CopyOffsets(winner, searched, keyframes, options).size(), 1u);
  options.copies.offsets = 0;
  EXPECT_TRUE(CopyOffsets(winner, searched, keyframes, options).empty());
  // Every other inlier voting halves the support.
  options.copies.offsets = 3;
  options.copies.max_voters = 30;
  const std::vector<CopyOffset> sampled = CopyOffsets(winner, searched, keyframes, options);
  ASSERT_GE(sampled.size(), 1u);
  EXPECT_EQ(sampled[0].support, 10);
}

TEST(CopyOffsetsTest, MappingErrorBeyondTheClusterRadiusScattersTheVotes) {
  std::mt19937 rng(22);
  LocatorOptions options;
  const PlaceVerdict winner = DeskWinner(&rng);
  // The same 20 things, each mapped up to 20 cm off: few agree within 5 cm.
  const std::vector<LocatorKeyframe> keyframes = {
      CopyOf(winner, 0, 20, {0.0f, 2.2f, 0.0f}, 0.2f, &rng)};
  EXPECT_TRUE(CopyOffsets(winner, {0}, keyframes, options).empty());
  options.copies.cluster_m = 0.4;
  const std::vector<CopyOffset> copies = CopyOffsets(winner, {0}, keyframes, options);
  ASSERT_EQ(copies.size(), 1u);
  EXPECT_LT((copies[0].offset - Eigen::Vector3d(0, 2.2, 0)).norm(), 0.1);
  // A winner without its inlier points is a caller's error.
  PlaceVerdict broken = winner;
  broken.inlier_points.pop_back();
  EXPECT_THROW(CopyOffsets(broken, {0}, keyframes, options), Error);
}

TEST(CopyOffsetsTest, TheBestSupportedCopiesAreKeptNotTheMostVoted) {
  std::mt19937 rng(23);
  LocatorOptions options;
  options.copies.offsets = 1;
  const PlaceVerdict winner = DeskWinner(&rng);
  // Ten things seen by four keyframes 3 m off (40 votes) against 20 things seen once 2.2 m off.
  std::vector<LocatorKeyframe> keyframes;
  for (int k = 0; k < 4; ++k)
    keyframes.push_back(CopyOf(winner, 0, 10, {3.0f, 0.0f, 0.0f}, 0.0f, &rng));
  keyframes.push_back(CopyOf(winner, 20, 20, {0.0f, 2.2f, 0.0f}, 0.0f, &rng));
  const std::vector<CopyOffset> copies = CopyOffsets(winner, {0, 1, 2, 3, 4}, keyframes, options);
  ASSERT_EQ(copies.size(), 1u);
  EXPECT_LT((copies[0].offset - Eigen::Vector3d(0, 2.2, 0)).norm(), 1e-4);
  EXPECT_EQ(copies[0].support, 20);
}

TEST(KeyframesAroundTest, SpreadOverPositionAndDirectionFromTheNearestSkippingTheGiven) {
  LocatorOptions options;  // around_m 5
  options.copies.around_keyframes = 3;
  std::vector<LocatorKeyframe> keyframes = {
      KeyframeAt({0.2, 0, 0}, 0),    // 0: nearest the centre
      KeyframeAt({0.3, 0, 0}, 0),    // 1: next to 0, the same way
      KeyframeAt({0.3, 0, 0}, 180),  // 2: there, turned round
      KeyframeAt({4, 0, 0}, 0),      // 3: across the room
      KeyframeAt({9, 0, 0}, 0),      // 4: beyond around_m
      KeyframeAt({1, 0, 0}, 0, 0),   // 5: no points
      KeyframeAt({-3, 0, 0}, 90),    // 6: skipped
      KeyframeAt({-4, 0, 0}, 180),   // 7: a synthetic view
  };
  keyframes[7].synthetic_view = SyntheticViewId(1);
  std::vector<size_t> chosen = KeyframesAround(Eigen::Vector3d::Zero(), {6}, keyframes, options);
  EXPECT_EQ(chosen, (std::vector<size_t>{0, 3, 2}));
  options.copies.around_keyframes = 10;
  chosen = KeyframesAround(Eigen::Vector3d::Zero(), {6}, keyframes, options);
  EXPECT_EQ(chosen, (std::vector<size_t>{0, 3, 2, 1}));
  options.copies.around_keyframes = 0;
  EXPECT_TRUE(KeyframesAround(Eigen::Vector3d::Zero(), {}, keyframes, options).empty());
}

TEST(PlaceSeeingTest, KeyframesNearThePoseThatSeeTheTargetHoldingMostOfItFirst) {
  LocatorOptions options;  // min_inliers 25, neighbour_radius_m 1, place_max_angle_deg
  auto seeing = [](const Eigen::Vector3d& at, double yaw_deg, int near_target, int elsewhere) {
    LocatorKeyframe keyframe = KeyframeAt(at, yaw_deg, 0);
    for (int i = 0; i < near_target; ++i) keyframe.world_points.emplace_back(0.01f * i, 0.0f, 3.0f);
    for (int i = 0; i < elsewhere; ++i) keyframe.world_points.emplace_back(9.0f, 9.0f, 0.0f);
    keyframe.descriptors = cv::Mat::zeros(near_target + elsewhere, 32, CV_8U);
    return keyframe;
  };
  std::vector<LocatorKeyframe> keyframes = {
      seeing({0.5, 0, 0}, 0, 30, 50),   // 0: near, the same way, 30 of the target
      seeing({-0.5, 0, 0}, 10, 60, 0),  // 1: near, 60 of it
      seeing({6, 0, 0}, 0, 90, 0),      // 2: beyond place_radius_m
      seeing({0, 0.5, 0}, 180, 90, 0),  // 3: looking the other way
      seeing({0, -0.5, 0}, 0, 10, 90),  // 4: too little of the target
      seeing({0, 0, 0}, 0, 200, 0),     // 5: a synthetic view
  };
  keyframes[5].synthetic_view = SyntheticViewId(1);
  const Eigen::Isometry3d pose = PoseAt({0, 0, 0}, 0);
  Place place = PlaceSeeing(pose, Eigen::Vector3d(0.1, 0, 3), keyframes, options);
  EXPECT_EQ(place.head, 1u);
  EXPECT_EQ(place.slots, (std::vector<size_t>{1, 0}));
  options.max_neighbours = 0;
  place = PlaceSeeing(pose, Eigen::Vector3d(0.1, 0, 3), keyframes, options);
  EXPECT_EQ(place.slots, (std::vector<size_t>{1}));
  EXPECT_TRUE(PlaceSeeing(pose, Eigen::Vector3d(4, 4, 3), keyframes, options).slots.empty());
}

// A place of two keyframes over random descriptors, and a photo holding some of them.
class MatchPlaceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(7);
    for (int k = 0; k < 2; ++k) {
      LocatorKeyframe keyframe = KeyframeAt({0.3 * k, 0, 0}, 0, 0);
      keyframe.descriptors = RandomDescriptors(40, &rng);
      for (int i = 0; i < 40; ++i) {
        keyframe.world_points.emplace_back(static_cast<float>(i), static_cast<float>(k), 3.0f);
      }
      keyframes_.push_back(std::move(keyframe));
    }
    place_.head = 0;
    place_.slots = {0, 1};
  }

  // A photo whose descriptor i is model row rows[i] with 5 bits flipped.
  PreparedPhoto PhotoOf(const std::vector<std::pair<size_t, int>>& keyframe_rows) const {
    PreparedPhoto photo;
    photo.size = cv::Size(640, 480);
    for (const auto& [slot, row] : keyframe_rows) {
      photo.features.descriptors.push_back(Flipped(keyframes_[slot].descriptors.row(row), 5));
      photo.points.emplace_back(static_cast<float>(10 * row), static_cast<float>(100 * slot));
    }
    return photo;
  }

  std::vector<LocatorKeyframe> keyframes_;
  Place place_;
};

TEST_F(MatchPlaceTest, DistinctDescriptorsMatchTheirPoints) {
  LocatorOptions options;
  const PreparedPhoto photo = PhotoOf({{0, 3}, {0, 17}, {1, 8}});
  const PlaceMatches matches = MatchPlace(photo, place_, keyframes_, options);
  EXPECT_EQ(matches.model_points.size(), 80u);
  EXPECT_EQ(matches.model_descriptors.rows, 80);
  ASSERT_EQ(matches.object.size(), 3u);
  EXPECT_EQ(matches.object_model, (std::vector<int>{3, 17, 48}));
  EXPECT_EQ(matches.model_slots[48], 1u);
  EXPECT_EQ(matches.object[2], cv::Point3f(8.0f, 1.0f, 3.0f));
  EXPECT_EQ(matches.image[1], photo.points[1]);
}

TEST_F(MatchPlaceTest, ARepeatedTextureFailsTheRatioTestUnlessItIsTheSamePoint) {
  LocatorOptions options;
  // Keyframe 1's row 5 shows keyframe 0's row 5 texture at another point (a poster printed
  // twice): the photo's descriptor cannot tell which.
  keyframes_[0].descriptors.row(5).copyTo(keyframes_[1].descriptors.row(5));
  PreparedPhoto photo = PhotoOf({{0, 5}});
  EXPECT_TRUE(MatchPlace(photo, place_, keyframes_, options).object.empty());
  // The same 3D point seen by both keyframes confirms the match.
  keyframes_[1].world_points[5] = keyframes_[0].world_points[5] + cv::Point3f(0.01f, 0.0f, 0.0f);
  const PlaceMatches matches = MatchPlace(photo, place_, keyframes_, options);
  ASSERT_EQ(matches.object.size(), 1u);
  EXPECT_LT(cv::norm(matches.object[0] - keyframes_[0].world_points[5]), 0.02);
}

TEST_F(MatchPlaceTest, DescriptorsTooFarFromAnyModelRowAreNotMatched) {
  LocatorOptions options;
  options.max_descriptor_distance = 3;
  EXPECT_TRUE(MatchPlace(PhotoOf({{0, 3}}), place_, keyframes_, options).object.empty());
  options.max_descriptor_distance = 5;
  EXPECT_EQ(MatchPlace(PhotoOf({{0, 3}}), place_, keyframes_, options).object.size(), 1u);
}

// 300 world points on three walls seen by a camera, a photo of them from a known pose, and a
// place whose keyframe stands near that pose.
class VerifyPlaceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(11);
    intrinsics_ = Intrinsics::FromPinhole(640, 480, 500.0, 500.0, 319.5, 239.5);
    photo_from_world_ = PoseAt({0.2, 0.0, -0.1}, 12).inverse();
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    LocatorKeyframe keyframe = KeyframeAt({0, 0, 0}, 0, 0);
    keyframe.descriptors = RandomDescriptors(300, &rng);
    photo_.size = cv::Size(640, 480);
    photo_.feature_candidates = {intrinsics_};
    photo_.intrinsics_given = true;
    photo_.detail_cells = 16;  // its features are over the whole view
    for (int i = 0; i < 300; ++i) {
      // Points 2-5 m ahead over the whole view.
      const Eigen::Vector3d cam(1.4 * u(rng), 1.0 * u(rng), 3.5 + 1.5 * u(rng));
      const Eigen::Vector3d world = photo_from_world_.inverse() * cam;
      keyframe.world_points.emplace_back(static_cast<float>(world.x()),
                                         static_cast<float>(world.y()),
                                         static_cast<float>(world.z()));
      const Eigen::Vector2d uv = intrinsics_.Project(cam);
      if (uv.x() < 0 || uv.y() < 0 || uv.x() >= 640 || uv.y() >= 480) continue;
      photo_.points.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
      photo_.features.descriptors.push_back(keyframe.descriptors.row(i).clone());
      photo_.features.keypoints.emplace_back(photo_.points.back(), 31.0f);
    }
    photo_.grid = PhotoGrid(photo_.points, 640, 480, LocatorOptions().guided_radius_px);
    keyframes_.push_back(std::move(keyframe));
    place_.head = 0;
    place_.slots = {0};
  }

  // The keyframe's thumbnail and the photo as the view check compares them, both of `wall`.
  void SeeWall(const testing::TexturedWall& wall, const ViewAgreementOptions& options) {
    cv::Mat grey;
    cv::Mat depth;
    wall.Render(keyframes_[0].world_from_cam, intrinsics_, &grey, &depth);
    keyframes_[0].thumbnail =
        std::make_shared<const KeyframeThumbnail>(MakeThumbnail(grey, depth, intrinsics_, options));
    PhotographWall(wall, options);
  }
  // The photo's image for the view check, of `wall`.
  void PhotographWall(const testing::TexturedWall& wall, const ViewAgreementOptions& options) {
    cv::Mat grey;
    cv::Mat depth;
    wall.Render(photo_from_world_.inverse(), intrinsics_, &grey, &depth);
    photo_.agreement_image = AgreementImage(grey, options);
  }

  Intrinsics intrinsics_;
  Eigen::Isometry3d photo_from_world_;
  PreparedPhoto photo_;
  std::vector<LocatorKeyframe> keyframes_;
  Place place_;
};

TEST_F(VerifyPlaceTest, TrueMatchesGiveThePhotosPoseAndPassEveryCheck) {
  LocatorOptions options;
  const PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  ASSERT_GT(matches.object.size(), 200u);
  const PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  ASSERT_TRUE(verdict.pose.valid);
  EXPECT_TRUE(verdict.accepted);
  const Eigen::Isometry3d world_from_photo = photo_from_world_.inverse();
  EXPECT_LT((verdict.pose.world_from_cam.translation() - world_from_photo.translation()).norm(),
            1e-3);
  EXPECT_LT(RotationAngleDeg(verdict.pose.world_from_cam.linear(), world_from_photo.linear()),
            0.05);
  EXPECT_EQ(verdict.inliers, static_cast<int>(matches.object.size()));
  EXPECT_EQ(verdict.cells, 16);
  // Each inlier's descriptor and cell of the 8x8 grid, for the twin search and Decide: inliers
  // in all 16 coarse cells lie in at least 16 fine ones.
  EXPECT_EQ(verdict.inlier_descriptors.rows, verdict.inliers);
  ASSERT_EQ(verdict.inlier_fine_cells.size(), static_cast<size_t>(verdict.inliers));
  uint64_t mask = 0;
  for (uint8_t cell : verdict.inlier_fine_cells) {
    ASSERT_LT(cell, 64);
    mask |= uint64_t{1} << cell;
  }
  EXPECT_EQ(verdict.fine_cell_mask, mask);
  EXPECT_GE(__builtin_popcountll(mask), 16);
  EXPECT_NEAR(verdict.rotation_deg, 12.0, 0.05);
  EXPECT_EQ(verdict.verified_slot, 0u);
  // Guided matching saw every place point that lands in the photo.
  EXPECT_EQ(verdict.projected, static_cast<int>(matches.object.size()));
}

TEST_F(VerifyPlaceTest, FromAPoseCentimetresOffTheWideSearchFindsThePointsAndTheTruePose) {
  LocatorOptions options;  // copies.search_radius_px 40
  // A copy's offset is known to a few centimetres: 8 cm across at 2-5 m is 8-20 px here, beyond
  // guided matching's 8 px window.
  PoseHypothesis rough;
  rough.valid = true;
  rough.intrinsics = intrinsics_;
  rough.world_from_cam = photo_from_world_.inverse();
  rough.world_from_cam.pretranslate(Eigen::Vector3d(0.08, 0.0, 0.0));
  const PlaceMatches wide = MatchPlaceFrom(photo_, place_, keyframes_, rough, options);
  EXPECT_EQ(wide.model_points.size(), keyframes_[0].world_points.size());
  EXPECT_GT(wide.object.size(), 0.9 * photo_.points.size());
  const PlaceVerdict verdict = VerifyPlace(photo_, place_, wide, keyframes_, options);
  ASSERT_TRUE(verdict.pose.valid);
  EXPECT_TRUE(verdict.accepted);
  EXPECT_LT((verdict.pose.world_from_cam.translation() - photo_from_world_.inverse().translation())
                .norm(),
            1e-3);
  // Within guided matching's own window most points are missed.
  options.copies.search_radius_px = options.guided_radius_px;
  const PlaceMatches narrow = MatchPlaceFrom(photo_, place_, keyframes_, rough, options);
  EXPECT_LT(narrow.object.size(), wide.object.size() / 2);
}

TEST_F(VerifyPlaceTest, APoseTurnedFarFromItsKeyframeIsRefusedAsThePaperSays) {
  LocatorOptions options;
  // The same points, but the keyframe that saw them looked the other way (120 deg).
  keyframes_[0].world_from_cam = PoseAt({0, 0, 0}, 132);
  const PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  const PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  ASSERT_TRUE(verdict.pose.valid);
  EXPECT_FALSE(verdict.accepted);
  EXPECT_NEAR(verdict.rotation_deg, 120.0, 0.1);
}

TEST_F(VerifyPlaceTest, InliersInOneCornerAreRefused) {
  LocatorOptions options;
  PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  // Only the matches in the photo's top-left quarter, and no guided growth beyond them.
  PlaceMatches corner = matches;
  corner.object.clear();
  corner.image.clear();
  corner.object_model.clear();
  for (size_t i = 0; i < matches.image.size(); ++i) {
    if (matches.image[i].x < 320 && matches.image[i].y < 240) {
      corner.object.push_back(matches.object[i]);
      corner.image.push_back(matches.image[i]);
      corner.object_model.push_back(matches.object_model[i]);
    }
  }
  ASSERT_GE(static_cast<int>(corner.object.size()), options.min_inliers);
  options.guided_rounds = 0;
  const PlaceVerdict verdict = VerifyPlace(photo_, place_, corner, keyframes_, options);
  ASSERT_TRUE(verdict.pose.valid);
  EXPECT_LE(verdict.cells, 4);
  options.min_inlier_cells = verdict.cells + 1;
  EXPECT_FALSE(VerifyPlace(photo_, place_, corner, keyframes_, options).accepted);
  options.min_inlier_cells = verdict.cells;
  EXPECT_TRUE(VerifyPlace(photo_, place_, corner, keyframes_, options).accepted);
  // A photo that shows little elsewhere needs fewer cells: the same corner is all it has.
  options.min_inlier_cells = verdict.cells + 1;
  options.min_inlier_cells_few_detail = verdict.cells;
  photo_.detail_cells = 2 * verdict.cells + 2;
  EXPECT_FALSE(VerifyPlace(photo_, place_, corner, keyframes_, options).accepted);
  photo_.detail_cells = 2 * verdict.cells + 1;
  EXPECT_TRUE(VerifyPlace(photo_, place_, corner, keyframes_, options).accepted);
}

TEST(RequiredInlierCellsTest, HalfThePhotosDetailCellsBetweenTheFewDetailFloorAndTheRule) {
  LocatorOptions options;  // min_inlier_cells 3, min_inlier_cells_few_detail 2
  PreparedPhoto photo;
  for (const auto& [detail, required] :
       std::vector<std::pair<int, int>>{{16, 3}, {6, 3}, {5, 2}, {4, 2}, {1, 2}, {0, 2}}) {
    photo.detail_cells = detail;
    EXPECT_EQ(RequiredInlierCells(photo, options), required) << detail << " detail cells";
  }
  // The floor never raises the rule.
  options.min_inlier_cells = 1;
  photo.detail_cells = 0;
  EXPECT_EQ(RequiredInlierCells(photo, options), 1);
}

TEST_F(VerifyPlaceTest, APoseWhoseViewIsUnlikeThePhotoIsRefusedLast) {
  LocatorOptions options;
  // The keyframe and the photo see a textured wall 3 m ahead; the matched points float in front
  // of it, as a repeated poster's would.
  SeeWall(testing::TexturedWall(), options.view_agreement);
  const PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_TRUE(verdict.accepted);
  EXPECT_TRUE(verdict.agreement.judged);
  EXPECT_GT(verdict.agreement.Score(), 0.9);
  EXPECT_FALSE(verdict.looks_different);

  // The same features in a photo of another wall: every other check passes, this one refuses.
  PhotographWall(testing::TexturedWall(3.0, /*seed=*/9), options.view_agreement);
  verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_TRUE(verdict.pose.valid);
  EXPECT_EQ(verdict.cells, 16);
  EXPECT_TRUE(verdict.agreement.judged);
  EXPECT_LT(verdict.agreement.Score(), options.min_view_agreement);
  EXPECT_TRUE(verdict.looks_different);
  EXPECT_FALSE(verdict.accepted);
  // Off, or without a thumbnail (a synthetic view), the check is not made.
  options.min_view_agreement = 0.0;
  verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_TRUE(verdict.accepted);
  EXPECT_FALSE(verdict.agreement.judged);
  options.min_view_agreement = LocatorOptions().min_view_agreement;
  keyframes_[0].thumbnail.reset();
  EXPECT_TRUE(VerifyPlace(photo_, place_, matches, keyframes_, options).accepted);
}

// A pose a cheaper check refused is view-checked too (Decide asks whether it looks like the
// photo before letting it make the photo ambiguous), and stays refused whatever its score.
TEST_F(VerifyPlaceTest, APoseACheaperCheckRefusedIsViewCheckedAndStaysRefused) {
  LocatorOptions options;
  SeeWall(testing::TexturedWall(), options.view_agreement);
  const PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  options.max_rotation_from_keyframe_deg = -1.0;  // the paper's check refuses every pose
  PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  ASSERT_GE(verdict.inliers, options.min_inliers);
  EXPECT_FALSE(verdict.accepted);
  EXPECT_TRUE(verdict.agreement.judged);
  EXPECT_GT(verdict.agreement.Score(), 0.9);
  EXPECT_FALSE(verdict.looks_different);
  EXPECT_FALSE(verdict.unconfirmed);
  // Of another wall: refused, and its view unlike the photo.
  PhotographWall(testing::TexturedWall(3.0, /*seed=*/9), options.view_agreement);
  verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_FALSE(verdict.accepted);
  EXPECT_TRUE(verdict.looks_different);
  // Fewer inliers than a pose needs: not measured.
  options.min_inliers = verdict.inliers + 1;
  verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_FALSE(verdict.agreement.judged);
  EXPECT_FALSE(verdict.looks_different);
}

TEST_F(VerifyPlaceTest, AWeakPoseTheViewCheckCannotJudgeIsRefused) {
  LocatorOptions options;
  // The keyframe's depth lies beyond what the check uses (a wall 8 m away): nothing to compare.
  SeeWall(testing::TexturedWall(8.0), options.view_agreement);
  const PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  options.min_inliers_unchecked = 0;
  PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  ASSERT_TRUE(verdict.accepted);
  EXPECT_FALSE(verdict.agreement.judged);
  EXPECT_FALSE(verdict.unconfirmed);

  options.min_inliers_unchecked = verdict.inliers + 1;
  verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_TRUE(verdict.unconfirmed);
  EXPECT_FALSE(verdict.looks_different);
  EXPECT_FALSE(verdict.accepted);
  const Decision decision = Decide({verdict}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kFewMatches);
  EXPECT_NE(decision.refusal->reason.find("could not be checked"), std::string::npos)
      << decision.refusal->reason;

  // As many inliers as needed without the check: accepted unjudged.
  options.min_inliers_unchecked = verdict.inliers;
  EXPECT_TRUE(VerifyPlace(photo_, place_, matches, keyframes_, options).accepted);
}

TEST_F(VerifyPlaceTest, RandomMatchesGiveNoAcceptedPose) {
  LocatorOptions options;
  PlaceMatches matches = MatchPlace(photo_, place_, keyframes_, options);
  std::mt19937 rng(3);
  std::shuffle(matches.image.begin(), matches.image.end(), rng);
  const PlaceVerdict verdict = VerifyPlace(photo_, place_, matches, keyframes_, options);
  EXPECT_FALSE(verdict.accepted);
  EXPECT_LT(verdict.inliers, options.min_inliers);
}

// A photo of a poster 6 m away in its upper right corner and of furniture 2-3 m away on its
// left, and a keyframe holding both as 3D points: the poster alone fixes the photo's pose only
// up to a slide sideways with a turn.
class SlideTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    intrinsics_ = Intrinsics::FromPinhole(640, 480, 500.0, 500.0, 319.5, 239.5);
    world_from_photo_ = PoseAt({0.0, 0.0, 0.0}, 0);
    LocatorKeyframe keyframe = KeyframeAt({0, 0, 0}, 0, 0);
    keyframe.descriptors = RandomDescriptors(kPoster + kFurniture, &rng);
    for (int i = 0; i < kPoster + kFurniture; ++i) {
      const Eigen::Vector3d cam =
          i < kPoster ? Eigen::Vector3d(1.4 + 0.5 * u(rng), -0.9 + 0.35 * u(rng), 5.0)
                      : Eigen::Vector3d(-0.7 + 0.3 * u(rng), 0.6 * u(rng), 2.5 + 0.5 * u(rng));
      const Eigen::Vector3d world = world_from_photo_ * cam;
      keyframe.world_points.emplace_back(static_cast<float>(world.x()),
                                         static_cast<float>(world.y()),
                                         static_cast<float>(world.z()));
      const Eigen::Vector2d uv = intrinsics_.Project(cam);
      photo_.points.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
      photo_.features.descriptors.push_back(keyframe.descriptors.row(i).clone());
      photo_.features.keypoints.emplace_back(photo_.points.back(), 31.0f);
      if (i < kPoster) poster_.push_back(keyframe.world_points.back());
    }
    photo_.size = cv::Size(640, 480);
    photo_.feature_candidates = {intrinsics_};
    photo_.intrinsics_given = true;
    photo_.grid = PhotoGrid(photo_.points, 640, 480, LocatorOptions().guided_radius_px);
    keyframes_.push_back(std::move(keyframe));
    place_.head = 0;
    place_.slots = {0};
  }

  // A winner whose inliers are the poster's points, at `world_from_cam`.
  PlaceVerdict PosterWinner(const Eigen::Isometry3d& world_from_cam) const {
    PlaceVerdict winner;
    winner.pose.valid = true;
    winner.pose.intrinsics = intrinsics_;
    winner.pose.world_from_cam = world_from_cam;
    for (int i = 0; i < kPoster; ++i) winner.pose.inliers.push_back(i);
    winner.inliers = kPoster;
    winner.inlier_points = poster_;
    winner.accepted = true;
    return winner;
  }

  static constexpr int kPoster = 150;
  static constexpr int kFurniture = 100;
  Intrinsics intrinsics_;
  Eigen::Isometry3d world_from_photo_;
  PreparedPhoto photo_;
  std::vector<cv::Point3f> poster_;
  std::vector<LocatorKeyframe> keyframes_;
  Place place_;
};

double PositionSd(const Eigen::Matrix<double, 6, 6>& covariance) {
  return std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance.topLeftCorner<3, 3>())
                       .eigenvalues()(2));
}

TEST_F(SlideTest, PoseCovarianceOfAFarPosterSpreadsFarMoreThanOfThePosterAndTheFurniture) {
  Eigen::Matrix<double, 6, 6> poster;
  ASSERT_TRUE(PoseCovariance(poster_, world_from_photo_, intrinsics_, &poster));
  Eigen::Matrix<double, 6, 6> both;
  ASSERT_TRUE(PoseCovariance(keyframes_[0].world_points, world_from_photo_, intrinsics_, &both));
  EXPECT_GT(PositionSd(poster), 0.15);  // a pose the slide moves (slide.min_sd_m)
  EXPECT_LT(PositionSd(both), 0.05);
  EXPECT_GT(PositionSd(poster), 5.0 * PositionSd(both));
  // Two points fix nothing.
  EXPECT_FALSE(PoseCovariance({poster_[0], poster_[1]}, world_from_photo_, intrinsics_, &both));
}

TEST_F(SlideTest, APoseSlidAlongTheFarPostersValleyFindsTheFurnitureAndTheTruePose) {
  // The photo's pose moved 2.9 sd along the poster's valley, turned to keep the poster in place:
  // the furniture then lands tens of pixels off, beyond guided matching's window.
  Eigen::Matrix<double, 6, 6> covariance;
  ASSERT_TRUE(PoseCovariance(poster_, world_from_photo_, intrinsics_, &covariance));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> position(covariance.topLeftCorner<3, 3>());
  const Eigen::Vector3d axis = position.eigenvectors().col(2);
  const Eigen::Vector3d turn =
      covariance.bottomLeftCorner<3, 3>() * covariance.topLeftCorner<3, 3>().inverse() * axis;
  const double along = 2.9 * std::sqrt(position.eigenvalues()(2));
  Eigen::Isometry3d off = world_from_photo_;
  off.translation() += along * axis;
  off.linear() = (Eigen::AngleAxisd(along * turn.norm(), turn.normalized()).toRotationMatrix() *
                  world_from_photo_.linear().transpose())
                     .transpose();
  ASSERT_GT((off.translation() - world_from_photo_.translation()).norm(), 0.4);

  const LocatorOptions options;
  const std::optional<PoseHypothesis> slid =
      SlideAlongWeakAxis(photo_, place_, keyframes_, PosterWinner(off), options);
  ASSERT_TRUE(slid.has_value());
  EXPECT_LT((slid->world_from_cam.translation() - world_from_photo_.translation()).norm(), 0.01);
  EXPECT_LT(RotationAngleDeg(slid->world_from_cam.linear(), world_from_photo_.linear()), 0.1);
  EXPECT_EQ(slid->inliers.size(), static_cast<size_t>(kPoster + kFurniture));

  // Off, or with a reach short of the pose's error, it stays where it was.
  LocatorOptions off_options;
  off_options.slide.min_sd_m = 0.0;
  EXPECT_FALSE(SlideAlongWeakAxis(photo_, place_, keyframes_, PosterWinner(off), off_options));
  LocatorOptions short_reach;
  short_reach.slide.reach_m = 0.05;
  EXPECT_FALSE(SlideAlongWeakAxis(photo_, place_, keyframes_, PosterWinner(off), short_reach));
}

TEST_F(SlideTest, APoseTheFurnitureFixesIsNotSlid) {
  PlaceVerdict winner = PosterWinner(world_from_photo_);
  winner.inlier_points = keyframes_[0].world_points;
  winner.pose.inliers.clear();
  for (int i = 0; i < kPoster + kFurniture; ++i) winner.pose.inliers.push_back(i);
  winner.inliers = kPoster + kFurniture;
  EXPECT_FALSE(SlideAlongWeakAxis(photo_, place_, keyframes_, winner, LocatorOptions()));
}

PlaceVerdict Verdict(int inliers, const Eigen::Vector3d& position, bool accepted,
                     double rotation_deg = 10.0, int cells = 12) {
  PlaceVerdict verdict;
  verdict.pose.valid = true;
  verdict.pose.world_from_cam = PoseAt(position, 0);
  verdict.inliers = inliers;
  verdict.accepted = accepted;
  verdict.rotation_deg = rotation_deg;
  verdict.cells = cells;
  verdict.required_cells = LocatorOptions().min_inlier_cells;  // a photo with detail everywhere
  return verdict;
}

TEST(DecideTest, MostInliersWinsAndAnAgreeingPoseIsNoRival) {
  const LocatorOptions options;
  const Decision decision = Decide(
      {Verdict(40, {0, 0, 0}, true), Verdict(100, {0.2, 0, 0}, true), PlaceVerdict()}, options);
  EXPECT_EQ(decision.winner, 1);
  EXPECT_EQ(decision.runner_up_inliers, 0);
  EXPECT_FALSE(decision.refusal.has_value());
}

TEST(DecideTest, TwoPlacesThatFitAboutAsWellAreAmbiguous) {
  const LocatorOptions options;  // the winner needs 1.5x the runner-up
  // The first winner, dethroned by a pose 4 m away, becomes its runner-up.
  Decision decision =
      Decide({Verdict(80, {0, 0, 0}, true), Verdict(100, {4, 0, 0}, true)}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  EXPECT_EQ(decision.runner_up_inliers, 80);
  EXPECT_NE(decision.refusal->reason.find("4.0 m apart"), std::string::npos);
  // Both are named, the one of most inliers (the answer it would have been) first.
  EXPECT_EQ(decision.ambiguous, (std::vector<int>{1, 0}));
  // Far enough ahead, the winner stands, and the runner-up is reported.
  decision = Decide({Verdict(60, {0, 0, 0}, true), Verdict(100, {4, 0, 0}, true)}, options);
  EXPECT_EQ(decision.winner, 1);
  EXPECT_EQ(decision.runner_up_inliers, 60);
  EXPECT_TRUE(decision.ambiguous.empty());
}

TEST(DecideTest, ARefusedPoseWithEnoughInliersStillMakesThePhotoAmbiguous) {
  const LocatorOptions options;
  // Refused for its inliers' spread, but 90 inliers elsewhere is a rival all the same; one with
  // fewer than min_inliers is not.
  Decision decision =
      Decide({Verdict(100, {0, 0, 0}, true), Verdict(90, {3, 0, 0}, false, 10.0, 2)}, options);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  decision =
      Decide({Verdict(30, {0, 0, 0}, true), Verdict(24, {3, 0, 0}, false, 10.0, 2)}, options);
  EXPECT_EQ(decision.winner, 0);
}

TEST(DecideTest, AnAmbiguousPhotosWouldBeAnswerIsItsWinnerElseTheStrongestRefusedPose) {
  const LocatorOptions options;
  const std::vector<PlaceVerdict> ambiguous = {Verdict(90, {3, 0, 0}, false, 10.0, 2),
                                               Verdict(80, {0, 0, 0}, true), PlaceVerdict()};
  ASSERT_TRUE(Decide(ambiguous, options).refusal.has_value());
  EXPECT_EQ(WouldBeAnswer(ambiguous), &ambiguous[1]);
  const std::vector<PlaceVerdict> refused = {Verdict(30, {0, 0, 0}, false),
                                             Verdict(60, {3, 0, 0}, false), PlaceVerdict()};
  EXPECT_EQ(WouldBeAnswer(refused), &refused[1]);
  EXPECT_EQ(WouldBeAnswer({PlaceVerdict(), PlaceVerdict()}), nullptr);
  EXPECT_EQ(WouldBeAnswer({}), nullptr);
}

// A verdict whose inliers lie in the given cells of the 8x8 grid, `per_cell` in each.
PlaceVerdict VerdictIn(int per_cell, const std::vector<int>& fine_cells,
                       const Eigen::Vector3d& position) {
  PlaceVerdict verdict =
      Verdict(per_cell * static_cast<int>(fine_cells.size()), position, /*accepted=*/true);
  for (int cell : fine_cells) {
    verdict.inlier_fine_cells.insert(verdict.inlier_fine_cells.end(), static_cast<size_t>(per_cell),
                                     static_cast<uint8_t>(cell));
    verdict.fine_cell_mask |= uint64_t{1} << cell;
  }
  verdict.inlier_centroid = position + Eigen::Vector3d(0, 0, 2);
  return verdict;
}

TEST(DecideTest, APoseWhoseViewWasUnlikeThePhotoIsNoRival) {
  const LocatorOptions options;
  // 90 inliers on the repeated poster in the other room, its view unlike the photo: the 100 of
  // the right place stand.
  PlaceVerdict other_room = Verdict(90, {3, 0, 0}, false);
  other_room.looks_different = true;
  Decision decision = Decide({Verdict(100, {0, 0, 0}, true), other_room}, options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_EQ(decision.runner_up_inliers, 0);
  EXPECT_FALSE(decision.refusal.has_value());
  // Alone, it is why the photo is not matched.
  other_room.agreement.judged = true;
  other_room.agreement.global_ncc = 0.6;
  other_room.agreement.cell_median_ncc = 0.12;
  decision = Decide({other_room, Verdict(20, {1, 0, 0}, false)}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kLooksDifferent);
  EXPECT_NE(decision.refusal->reason.find("(90 inliers) fits details that repeat elsewhere"),
            std::string::npos)
      << decision.refusal->reason;
  EXPECT_NE(decision.refusal->reason.find("agreement 0.12, 0.55 needed"), std::string::npos)
      << decision.refusal->reason;
}

TEST(DecideTest, MoreInliersOnTheSamePartOfThePhotoAsTheRunnerUpAreAmbiguous) {
  const LocatorOptions options;  // 10% of the winner's inliers where the runner-up has none
  // The wrong one of two identical desks: three times the inliers, all where the other has some.
  Decision decision = Decide(
      {VerdictIn(30, {9, 10, 17, 18}, {0, 0, 0}), VerdictIn(10, {9, 10, 17, 18}, {2.2, 0, 0})},
      options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  EXPECT_NE(decision.refusal->reason.find("same part of the photo"), std::string::npos);
  EXPECT_EQ(decision.runner_up_inliers, 40);
  // The right desk with the poster behind it: a fifth of its inliers where the twin has none.
  decision = Decide(
      {VerdictIn(30, {9, 10, 17, 18, 40}, {0, 0, 0}), VerdictIn(10, {9, 10, 17, 18}, {2.2, 0, 0})},
      options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_FALSE(decision.refusal.has_value());
  // The same things from a pose 0.9 m along the view (another focal length): not a copy.
  PlaceVerdict same_things = VerdictIn(10, {9, 10, 17, 18}, {0.9, 0, 0});
  same_things.inlier_centroid = Eigen::Vector3d(0.1, 0, 2);
  decision = Decide({VerdictIn(30, {9, 10, 17, 18}, {0, 0, 0}), same_things}, options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_EQ(decision.runner_up_inliers, 40);
  // A pose that agrees with the winner is no rival, wherever its inliers are.
  decision = Decide(
      {VerdictIn(30, {9, 10, 17, 18}, {0, 0, 0}), VerdictIn(10, {9, 10, 17, 18}, {0.2, 0, 0})},
      options);
  EXPECT_EQ(decision.winner, 0);
}

// A verdict that passed every check with the view check's score `agreement` (< 0: not judged).
PlaceVerdict Judged(int inliers, const Eigen::Vector3d& position, double agreement, bool copy) {
  PlaceVerdict verdict = Verdict(inliers, position, /*accepted=*/true);
  verdict.agreement.judged = agreement >= 0.0;
  verdict.agreement.global_ncc = verdict.agreement.cell_median_ncc = std::max(0.0, agreement);
  verdict.copy = copy;
  return verdict;
}

TEST(DecideTest, BetweenCopiesTheViewCheckDecidesNotTheInliers) {
  const LocatorOptions options;  // copies.min_agreement_lead 0.05
  // The desk the walk saw well, its surroundings like the photo's; the copy 2.2 m along, seen from
  // another side, its surroundings not: the winner stands, the copy reported as runner-up.
  Decision decision =
      Decide({Judged(400, {0, 0, 0}, 0.95, false), Judged(60, {0, 2.2, 0}, 0.60, true)}, options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_EQ(decision.runner_up_inliers, 60);
  // The other way round: fewer inliers on the copy, but its surroundings are the photo's.
  decision =
      Decide({Judged(424, {0, 0, 0}, 0.67, false), Judged(244, {0, 2.2, 0}, 0.94, true)}, options);
  EXPECT_EQ(decision.winner, 1);
  EXPECT_EQ(decision.runner_up_inliers, 424);
  // Alike within the lead: ambiguous, whatever the counts.
  decision =
      Decide({Judged(371, {0, 0, 0}, 0.89, false), Judged(69, {0, 2.2, 0}, 0.90, true)}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  EXPECT_NE(decision.refusal->reason.find("a copy of what the photo shows 2.2 m away"),
            std::string::npos)
      << decision.refusal->reason;
  EXPECT_EQ(decision.ambiguous, (std::vector<int>{1, 0}));  // the view check's leader first
  // A copy the view check could not judge does not lead, and a refused copy is no rival: nor
  // is it a runner-up to the count rules (its 300 inliers would make the photo ambiguous).
  decision =
      Decide({Judged(400, {0, 0, 0}, 0.8, false), Judged(90, {0, 2.2, 0}, -1.0, true)}, options);
  EXPECT_EQ(decision.winner, 0);
  PlaceVerdict refused = Judged(300, {0, 2.2, 0}, 0.3, true);
  refused.accepted = false;
  decision = Decide({Judged(400, {0, 0, 0}, 0.8, false), refused}, options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_EQ(decision.runner_up_inliers, 0);
  // Without copies the count rules stand as before.
  EXPECT_FALSE(
      DecideAmongCopies({Judged(400, {0, 0, 0}, 0.8, false), Verdict(300, {0, 2.2, 0}, true)}, 0,
                        options)
          .has_value());
  EXPECT_THROW(DecideAmongCopies({}, 0, options), Error);
}

TEST(DecideTest, BetweenPlacesThatFitAboutAsWellTheViewCheckDecidesWhenOneLeadsClearly) {
  LocatorOptions options;  // ambiguity_min_agreement_lead 0.05
  // Ceiling tiles one tile apart: 144 and 139 inliers, the runner-up's surroundings the photo's.
  Decision decision =
      Decide({Judged(144, {0, 0, 0}, 0.77, false), Judged(139, {0.8, 0, 0}, 0.89, false)}, options);
  EXPECT_EQ(decision.winner, 1);
  EXPECT_EQ(decision.runner_up_inliers, 144);
  EXPECT_TRUE(decision.runner_up_pose.translation().isApprox(Eigen::Vector3d::Zero()));
  // The winner by inliers leads the view too: it stands.
  decision =
      Decide({Judged(57, {0, 0, 0}, 0.93, false), Judged(57, {3, 0, 0}, 0.73, false)}, options);
  EXPECT_EQ(decision.winner, 0);
  // Within the lead, or one not judged: ambiguous as before.
  decision =
      Decide({Judged(31, {0, 0, 0}, 0.94, false), Judged(26, {6, 0, 0}, 0.97, false)}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  decision =
      Decide({Judged(100, {0, 0, 0}, -1.0, false), Judged(90, {4, 0, 0}, 0.9, false)}, options);
  EXPECT_EQ(decision.winner, -1);
  // A refused runner-up that looks more like the photo does not win: the photo stays ambiguous.
  PlaceVerdict refused = Judged(110, {4, 0, 0}, 0.95, false);
  refused.accepted = false;
  decision = Decide({Judged(100, {0, 0, 0}, 0.6, false), refused}, options);
  EXPECT_EQ(decision.winner, -1);
  // Led by it, the accepted one stands.
  refused.agreement.global_ncc = refused.agreement.cell_median_ncc = 0.7;
  decision = Decide({Judged(100, {0, 0, 0}, 0.9, false), refused}, options);
  EXPECT_EQ(decision.winner, 0);
  // Off: ambiguous whatever the views.
  options.ambiguity_min_agreement_lead = 0.0;
  decision =
      Decide({Judged(144, {0, 0, 0}, 0.77, false), Judged(139, {0.8, 0, 0}, 0.89, false)}, options);
  EXPECT_EQ(decision.winner, -1);
}

TEST(DecideTest, EveryPoseThatFitsAboutAsWellCompetesOnTheView) {
  const LocatorOptions options;  // 1.5x the inliers, ambiguity_min_agreement_lead 0.05
  // A printer with one picture on every face: two poses facing the wrong faces (158 and 138
  // inliers) and the right one (134), whose view the check scores far above both.
  const std::vector<PlaceVerdict> printer = {Judged(158, {2.7, 0, 0}, 0.64, false),
                                             Judged(138, {1.8, 1.2, 0}, 0.56, false),
                                             Judged(134, {0, 0, 0}, 0.97, false)};
  Decision decision = Decide(printer, options);
  EXPECT_EQ(decision.winner, 2);
  EXPECT_EQ(decision.runner_up_inliers, 158);
  EXPECT_TRUE(decision.runner_up_pose.translation().isApprox(Eigen::Vector3d(2.7, 0, 0)));
  // The leader must lead every pose placed elsewhere: 0.97 against 0.95 is no lead.
  std::vector<PlaceVerdict> close = printer;
  close[1] = Judged(138, {1.8, 1.2, 0}, 0.95, false);
  decision = Decide(close, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  // ... but not a pose agreeing with it (the same place found twice).
  close[1] = Judged(138, {0.1, 0, 0}, 0.95, false);
  decision = Decide(close, options);
  EXPECT_EQ(decision.winner, 2);
  // A refused leader does not win, and a pose the check could not judge leaves the photo
  // ambiguous.
  std::vector<PlaceVerdict> refused = printer;
  refused[2].accepted = false;
  EXPECT_EQ(Decide(refused, options).winner, -1);
  std::vector<PlaceVerdict> unjudged = printer;
  unjudged[1] = Judged(138, {1.8, 1.2, 0}, -1.0, false);
  EXPECT_EQ(Decide(unjudged, options).winner, -1);
  // Too few inliers to fit about as well (158 > 1.5 x 100): no rival, the count stands.
  std::vector<PlaceVerdict> weak = printer;
  weak[1] = Judged(100, {1.8, 1.2, 0}, 0.56, false);
  weak[2] = Judged(100, {0, 0, 0}, 0.97, false);
  decision = Decide(weak, options);
  EXPECT_EQ(decision.winner, 0);
}

TEST(DecideTest, AStrongerPoseTheViewCheckHalfRefusedMakesThePhotoAmbiguous) {
  LocatorOptions options;  // ambiguity_min_doubted_agreement 0.40, 1.5x the inliers
  // A ceiling light: 57 inliers on the repeated fitting 4.5 m away whose view scores 0.79; the
  // right pose fits 125 but its view check scored 0.45, under min_view_agreement.
  PlaceVerdict right = Judged(125, {4.5, 0, 0}, 0.45, false);
  right.accepted = false;
  right.looks_different = true;
  Decision decision = Decide({Judged(57, {0, 0, 0}, 0.79, false), right}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kAmbiguous);
  EXPECT_EQ(decision.ambiguous, (std::vector<int>{0, 1}));
  EXPECT_EQ(decision.runner_up_inliers, 125);
  EXPECT_NE(decision.refusal->reason.find("a place 4.5 m away fits 125 of the photo's features "
                                          "against the answer's 57, and looks partly like it "
                                          "(agreement 0.45)"),
            std::string::npos)
      << decision.refusal->reason;
  // One whose view is plainly another (0.19), or without 1.5x the inliers, or at the answer's
  // place, or on the ceiling alone, leaves the answer standing.
  for (auto change : std::vector<std::function<void(PlaceVerdict*)>>{
           [](PlaceVerdict* v) { v->agreement.global_ncc = v->agreement.cell_median_ncc = 0.19; },
           [](PlaceVerdict* v) { v->inliers = 85; },
           [](PlaceVerdict* v) {
             v->pose.world_from_cam = PoseAt({0.1, 0, 0}, 0);
           },
           [](PlaceVerdict* v) { v->ceiling_only = true; }}) {
    PlaceVerdict rival = right;
    change(&rival);
    decision = Decide({Judged(57, {0, 0, 0}, 0.79, false), rival}, options);
    EXPECT_EQ(decision.winner, 0);
    EXPECT_FALSE(decision.refusal.has_value());
  }
  // Off.
  options.ambiguity_min_doubted_agreement = 0.0;
  EXPECT_EQ(Decide({Judged(57, {0, 0, 0}, 0.79, false), right}, options).winner, 0);
  options.ambiguity_min_doubted_agreement = 1.5;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("ambiguity_min_doubted_agreement"), std::string::npos) << error;
}

TEST(ExplainBareViewTest, FailedMatchingOnAPhotoOfFewDetailCellsAsksForMoreOfTheRoom) {
  LocatorOptions options;
  options.bare_view_max_detail_cells = 3;
  const Refusal few{UnmatchedReason::kFewMatches, "12 PnP inliers at best, 25 needed."};
  const Refusal bare = ExplainBareView(few, 3, options);
  EXPECT_EQ(bare.code, UnmatchedReason::kBareView);
  EXPECT_EQ(bare.reason,
            "the photo shows little detail (its features fill 3 of 16 parts of it); 12 PnP "
            "inliers at best, 25 needed.");
  for (const UnmatchedReason code :
       {UnmatchedReason::kUnknownPlace, UnmatchedReason::kUnseenView,
        UnmatchedReason::kMatchesInOneCorner, UnmatchedReason::kLooksDifferent}) {
    EXPECT_EQ(ExplainBareView(Refusal{code, "why"}, 1, options).code, UnmatchedReason::kBareView);
  }
  // Detail in more cells: the matcher's own reason stands.
  const Refusal detailed = ExplainBareView(few, 4, options);
  EXPECT_EQ(detailed.code, UnmatchedReason::kFewMatches);
  EXPECT_EQ(detailed.reason, few.reason);
  // Two places fit, the photo is empty, or it has too few features: not a matter of framing.
  for (const UnmatchedReason code :
       {UnmatchedReason::kAmbiguous, UnmatchedReason::kEmptyPhoto, UnmatchedReason::kFewFeatures}) {
    const Refusal kept = ExplainBareView(Refusal{code, "why"}, 0, options);
    EXPECT_EQ(kept.code, code);
    EXPECT_EQ(kept.reason, "why");
  }
}

TEST(DecideTest, NothingAcceptedSaysWhyFromTheBestRefusedPose) {
  const LocatorOptions options;
  Decision decision =
      Decide({Verdict(50, {0, 0, 0}, false, 120.0), Verdict(20, {1, 0, 0}, false)}, options);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kUnseenView);
  EXPECT_NE(decision.refusal->reason.find("turns 120 deg"), std::string::npos);

  decision = Decide({Verdict(50, {0, 0, 0}, false, 10.0, 2)}, options);
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kMatchesInOneCorner);
  EXPECT_NE(decision.refusal->reason.find("in 2 cells"), std::string::npos);

  // Enough inliers over enough of the photo, but few of the points the pose projects into it.
  PlaceVerdict few_of_the_projected = Verdict(147, {0, 0, 0}, false, 10.0, 8);
  few_of_the_projected.projected = 18000;
  decision = Decide({few_of_the_projected}, options);
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kFewMatches);
  EXPECT_NE(decision.refusal->reason.find("147 PnP inliers at best, only 0.8% of the 18000"),
            std::string::npos)
      << decision.refusal->reason;
  EXPECT_EQ(decision.refusal->reason.find("cells"), std::string::npos) << decision.refusal->reason;

  decision = Decide({Verdict(12, {0, 0, 0}, false), PlaceVerdict()}, options);
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kFewMatches);
  EXPECT_NE(decision.refusal->reason.find("none of 2 retrieved places"), std::string::npos);
  EXPECT_NE(decision.refusal->reason.find("12 PnP inliers"), std::string::npos);

  EXPECT_EQ(Decide({}, options).refusal->code, UnmatchedReason::kFewMatches);
}

// A verdict whose inliers lie at the given heights (z up), spread over 2 x 2 m, its camera at
// 1.6 m.
PlaceVerdict VerdictWithInliersAt(const std::vector<double>& heights) {
  PlaceVerdict verdict = Verdict(static_cast<int>(heights.size()), {0, 0, 1.6}, true);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> across(-1.0f, 1.0f);
  for (double z : heights) {
    verdict.inlier_points.emplace_back(across(rng), 2.0f + across(rng), static_cast<float>(z));
  }
  return verdict;
}

// A ceiling's tiles and lights repeat across the building: a pose whose inliers lie on it alone is
// one guess among the repeats. Inliers on a desk below the camera, on a wall (spread in height),
// or a ceiling with a wall's points in it are not; a few stray points do not hide a ceiling.
TEST(RestsOnCeilingOnlyTest, InliersOnOneHorizontalPlaneAboveTheCameraAlone) {
  const LocatorOptions options;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  std::vector<double> ceiling(40, 2.78);
  for (size_t i = 0; i < ceiling.size(); ++i) ceiling[i] += 0.001 * static_cast<double>(i % 7);
  EXPECT_TRUE(RestsOnCeilingOnly(VerdictWithInliersAt(ceiling), up, options));
  std::vector<double> with_strays = ceiling;
  with_strays[0] = 1.2;  // two stray points: under the 10th percentile
  with_strays[1] = 2.1;
  EXPECT_TRUE(RestsOnCeilingOnly(VerdictWithInliersAt(with_strays), up, options));
  // Up is the model's, whatever its axes: the same points in a frame whose up is its y.
  PlaceVerdict turned = VerdictWithInliersAt(ceiling);
  const Eigen::Isometry3d turned_frame(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()));
  for (cv::Point3f& point : turned.inlier_points) {
    const Eigen::Vector3d p = turned_frame * Eigen::Vector3d(point.x, point.y, point.z);
    point = cv::Point3f(static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z()));
  }
  turned.pose.world_from_cam = turned_frame * turned.pose.world_from_cam;
  EXPECT_TRUE(RestsOnCeilingOnly(turned, turned_frame * up, options));
  EXPECT_FALSE(RestsOnCeilingOnly(turned, up, options));

  EXPECT_FALSE(RestsOnCeilingOnly(VerdictWithInliersAt(std::vector<double>(40, 0.75)), up, options))
      << "a desk below the camera";
  std::vector<double> wall;
  for (int i = 0; i < 40; ++i) wall.push_back(1.0 + 0.04 * i);
  EXPECT_FALSE(RestsOnCeilingOnly(VerdictWithInliersAt(wall), up, options));
  std::vector<double> ceiling_and_wall = ceiling;
  for (int i = 0; i < 10; ++i) ceiling_and_wall.push_back(1.2 + 0.1 * i);
  EXPECT_FALSE(RestsOnCeilingOnly(VerdictWithInliersAt(ceiling_and_wall), up, options));
  LocatorOptions off;
  off.ceiling_only_max_thickness_m = 0.0;
  EXPECT_FALSE(RestsOnCeilingOnly(VerdictWithInliersAt(ceiling), up, off));
  off.ceiling_only_max_thickness_m = -0.1;
  std::string error;
  EXPECT_FALSE(off.Check(&error));
  EXPECT_NE(error.find("ceiling_only_max_thickness_m"), std::string::npos) << error;
}

// A pose on the ceiling alone wins nothing, makes no photo ambiguous, and says what to do.
TEST(DecideTest, APoseOnTheCeilingAloneIsNoAnswerAndNoRival) {
  const LocatorOptions options;
  PlaceVerdict ceiling = Verdict(90, {3, 0, 0}, false);
  ceiling.ceiling_only = true;
  Decision decision = Decide({Verdict(100, {0, 0, 0}, true), ceiling}, options);
  EXPECT_EQ(decision.winner, 0);
  EXPECT_EQ(decision.runner_up_inliers, 0);
  decision = Decide({ceiling, Verdict(20, {1, 0, 0}, false)}, options);
  EXPECT_EQ(decision.winner, -1);
  ASSERT_TRUE(decision.refusal.has_value());
  EXPECT_EQ(decision.refusal->code, UnmatchedReason::kBareView);
  EXPECT_NE(decision.refusal->reason.find("(90 inliers) rests on the ceiling alone"),
            std::string::npos)
      << decision.refusal->reason;
  EXPECT_NE(decision.refusal->reason.find("include a wall or furniture"), std::string::npos);
}

// A photo with corners everywhere: random rectangles of random greys.
cv::Mat TexturedPhoto(int width, int height) {
  cv::Mat photo(height, width, CV_8UC3, cv::Scalar::all(128));
  cv::RNG rng(5);
  const int side = std::max(8, std::min(width, height) / 12);
  for (int i = 0; i < width * height / (side * side) * 4; ++i) {
    const cv::Point corner(rng.uniform(0, width), rng.uniform(0, height));
    const cv::Point size(rng.uniform(side / 2, side), rng.uniform(side / 2, side));
    cv::rectangle(photo, corner, corner + size, cv::Scalar::all(rng.uniform(0, 256)), cv::FILLED);
  }
  return photo;
}

TEST(PreparePhotoTest, ALargePhotoIsDownscaledAndEveryFocalCandidateScaledWithIt) {
  LocatorOptions options;
  const PreparedPhoto prepared = PreparePhoto(TexturedPhoto(2560, 1920), std::nullopt, options);
  ASSERT_FALSE(prepared.refusal.has_value());
  EXPECT_EQ(prepared.size, cv::Size(960, 720));
  ASSERT_EQ(prepared.full_candidates.size(), options.focal_candidates_35mm.size());
  ASSERT_EQ(prepared.feature_candidates.size(), options.focal_candidates_35mm.size());
  EXPECT_EQ(prepared.full_candidates[0].width, 2560);
  EXPECT_NEAR(prepared.feature_candidates[0].fx, prepared.full_candidates[0].fx * 960 / 2560, 1e-6);
  EXPECT_FALSE(prepared.intrinsics_given);
  EXPECT_GT(prepared.features.size(), 1000u);
  EXPECT_EQ(prepared.points.size(), prepared.features.size());
  EXPECT_EQ(prepared.detail_cells, 16);
}

// A photo in dim light: its RootSIFT keypoints are found down to sift_photo_features' contrast
// threshold, whatever the keyframes' (sift_features) is.
TEST(PreparePhotoTest, APalePhotosRootSiftUsesThePhotoContrastThreshold) {
  cv::Mat pale;
  TexturedPhoto(1280, 960).convertTo(pale, CV_8UC3, 0.2, 102.0);  // grey levels 102-153
  const auto count = [&pale](double keyframe_threshold, double photo_threshold) {
    LocatorOptions options;
    options.sift_features.sift_contrast_threshold = keyframe_threshold;
    options.sift_photo_features.sift_contrast_threshold = photo_threshold;
    options.sift_photo_features.max_features = 1000;
    const PreparedPhoto sift =
        RootSiftPhoto(pale, PreparePhoto(pale, std::nullopt, options), options);
    return sift.refusal ? size_t{0} : sift.features.size();
  };
  const size_t at_default =
      count(0.04, LocatorOptions().sift_photo_features.sift_contrast_threshold);
  const size_t at_keyframes = count(0.04, 0.04);
  std::printf("pale photo RootSIFT keypoints: %zu at the photo default, %zu at 0.04\n", at_default,
              at_keyframes);
  EXPECT_GT(at_default, 2 * at_keyframes);
  EXPECT_GT(at_keyframes, 0u);
  EXPECT_EQ(count(0.08, 0.04), at_keyframes);
}

// RootSIFT's photo: matched at sift_image_side_px with 128-byte rows, while retrieval keeps the
// ORB descriptors and the detail cells of PreparePhoto; a blank photo is refused, a narrow one
// too short to hold features.
TEST(PreparePhotoTest, TheRootSiftPhotoIsMatchedAtItsOwnScaleAndRetrievedByOrb) {
  LocatorOptions options;
  const cv::Mat photo = TexturedPhoto(2560, 1920);
  const PreparedPhoto orb = PreparePhoto(photo, std::nullopt, options);
  const PreparedPhoto sift = RootSiftPhoto(photo, orb, options);
  ASSERT_FALSE(sift.refusal.has_value()) << sift.refusal->reason;
  EXPECT_EQ(sift.size, cv::Size(640, 480));
  ASSERT_EQ(sift.feature_candidates.size(), orb.full_candidates.size());
  EXPECT_NEAR(sift.feature_candidates[0].fx, orb.full_candidates[0].fx * 640 / 2560, 1e-6);
  EXPECT_EQ(sift.features.descriptors.cols, 128);
  EXPECT_GT(sift.features.size(), 300u);
  EXPECT_LE(sift.features.size(), static_cast<size_t>(options.sift_photo_features.max_features));
  EXPECT_EQ(sift.points.size(), sift.features.size());
  for (const cv::Point2f& p : sift.points) EXPECT_LT(p.x, 640.0f);
  EXPECT_EQ(sift.retrieval_descriptors.cols, 32);
  EXPECT_EQ(sift.retrieval_descriptors.rows, orb.features.descriptors.rows);
  EXPECT_EQ(sift.detail_cells, orb.detail_cells);

  const cv::Mat blank(480, 640, CV_8UC3, cv::Scalar::all(128));
  const PreparedPhoto refused =
      RootSiftPhoto(blank, PreparePhoto(blank, std::nullopt, options), options);
  ASSERT_TRUE(refused.refusal.has_value());
  EXPECT_EQ(refused.refusal->code, UnmatchedReason::kFewFeatures);
  // 4000x300 is matched at 640x48 by RootSIFT: too short a side.
  const cv::Mat narrow = TexturedPhoto(4000, 300);
  const PreparedPhoto short_side =
      RootSiftPhoto(narrow, PreparePhoto(narrow, std::nullopt, options), options);
  ASSERT_TRUE(short_side.refusal.has_value());
  EXPECT_NE(short_side.refusal->reason.find("640x48"), std::string::npos)
      << short_side.refusal->reason;
}

TEST(PreparePhotoTest, GivenIntrinsicsForAnotherSizeAreScaledToThePhoto) {
  LocatorOptions options;
  const Intrinsics half = Intrinsics::FromPinhole(320, 240, 250.0, 250.0, 159.5, 119.5);
  const PreparedPhoto prepared = PreparePhoto(TexturedPhoto(640, 480), half, options);
  ASSERT_EQ(prepared.full_candidates.size(), 1u);
  EXPECT_TRUE(prepared.intrinsics_given);
  EXPECT_EQ(prepared.full_candidates[0].width, 640);
  EXPECT_NEAR(prepared.full_candidates[0].fx, 500.0, 1e-9);
  EXPECT_EQ(prepared.size, cv::Size(640, 480));
  Intrinsics broken = half;
  broken.fx = -1.0;
  EXPECT_THROW(PreparePhoto(TexturedPhoto(640, 480), broken, options), Error);
}

TEST(PreparePhotoTest, ABlankOrNarrowPhotoIsRefusedForTooFewFeatures) {
  LocatorOptions options;
  PreparedPhoto prepared =
      PreparePhoto(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(128)), std::nullopt, options);
  ASSERT_TRUE(prepared.refusal.has_value());
  EXPECT_EQ(prepared.refusal->code, UnmatchedReason::kFewFeatures);
  EXPECT_EQ(prepared.detail_cells, 0);
  // 4000x100 downscales to 960x24: too short a side to hold features.
  prepared = PreparePhoto(TexturedPhoto(4000, 100), std::nullopt, options);
  ASSERT_TRUE(prepared.refusal.has_value());
  EXPECT_NE(prepared.refusal->reason.find("960x24"), std::string::npos);
}

// A photo taken past a board that stands in front of a wall, and a place whose verified keyframe
// stood between the board and the wall (it saw the wall only) while another stood near the photo.
class JudgeViewAgainTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Intrinsics keyframe_camera =
        Intrinsics::FromPinhole(640, 480, 525.0, 525.0, 319.5, 239.5);
    const auto add = [&](const Eigen::Vector3d& position, double yaw_deg) {
      LocatorKeyframe keyframe = KeyframeAt(position, yaw_deg);
      cv::Mat grey;
      cv::Mat depth;
      scene_.Render(keyframe.world_from_cam, keyframe_camera, &grey, &depth);
      keyframe.thumbnail = std::make_shared<const KeyframeThumbnail>(
          MakeThumbnail(grey, depth, keyframe_camera, options_.view_agreement));
      keyframes_.push_back(std::move(keyframe));
    };
    add({-0.2, 0, 2.2}, 0);    // 0: verified, behind the board
    add({0.3, 0.1, 0.3}, -5);  // 1: near the photo, sees the board
    add({0.0, 0.0, -4.0}, 0);  // 2: 4 m behind the photo
    add({0.2, 0.0, 0.2}, 90);  // 3: beside the photo, turned 90 degrees
    add({-0.3, 0.0, 0.1}, 5);  // 4: near the photo, but a synthetic view (no thumbnail)
    keyframes_[4].thumbnail.reset();
    place_.head = 0;
    place_.slots = {0, 1, 2, 3, 4};

    const Intrinsics photo_camera =
        Intrinsics::FromPinhole(1280, 960, 1000.0, 1000.0, 639.5, 479.5);
    cv::Mat grey;
    cv::Mat depth;
    scene_.Render(PoseAt({0, 0, 0}, 0), photo_camera, &grey, &depth);
    photo_.agreement_image = AgreementImage(grey, options_.view_agreement);
    // Refused by the view check alone, as VerifyPlace leaves such a pose.
    verdict_.pose.valid = true;
    verdict_.pose.world_from_cam = PoseAt({0, 0, 0}, 0);
    verdict_.pose.intrinsics = photo_camera;
    verdict_.verified_slot = 0;
    verdict_.inliers = 120;
    verdict_.passed_other_checks = true;
    verdict_.looks_different = true;
  }

  testing::WallBehindBoard scene_;
  LocatorOptions options_;
  std::vector<LocatorKeyframe> keyframes_;
  Place place_;
  PreparedPhoto photo_;
  PlaceVerdict verdict_;
};

TEST_F(JudgeViewAgainTest, TheVerifiedKeyframeAndThoseStandingNearThePoseLookingItsWay) {
  EXPECT_EQ(SecondOpinionKeyframes(verdict_, place_, keyframes_, options_),
            (std::vector<size_t>{0, 1}));
  options_.view_second_opinion.radius_m = 5.0;  // keyframe 2 within reach now
  EXPECT_EQ(SecondOpinionKeyframes(verdict_, place_, keyframes_, options_),
            (std::vector<size_t>{0, 1, 2}));
  options_.view_second_opinion.keyframes = 1;  // the nearest only
  EXPECT_EQ(SecondOpinionKeyframes(verdict_, place_, keyframes_, options_),
            (std::vector<size_t>{0, 1}));
  options_.view_second_opinion.max_angle_deg = 95.0;  // keyframe 3 too, and it is nearest
  EXPECT_EQ(SecondOpinionKeyframes(verdict_, place_, keyframes_, options_),
            (std::vector<size_t>{0, 3}));
}

TEST_F(JudgeViewAgainTest, APoseTheVerifiedKeyframeSawPastFurnitureIsAccepted) {
  // The verified keyframe alone finds the photo unlike its view.
  const LocatorKeyframe& verified = keyframes_[0];
  const ViewAgreement alone = MeasureViewAgreement(
      photo_.agreement_image, verdict_.pose.intrinsics, verdict_.pose.world_from_cam,
      *verified.thumbnail, verified.world_from_cam, options_.view_agreement);
  ASSERT_TRUE(alone.judged);
  ASSERT_LT(alone.Score(), options_.min_view_agreement);
  PlaceVerdict verdict = verdict_;
  EXPECT_TRUE(JudgeViewAgain(photo_, place_, keyframes_, options_, &verdict));
  EXPECT_TRUE(verdict.accepted);
  EXPECT_FALSE(verdict.looks_different);
  EXPECT_GT(verdict.agreement.Score(), 0.8);
}

TEST_F(JudgeViewAgainTest, OnlyAPoseTheViewCheckAloneRefusedIsJudgedAgain) {
  const auto unchanged = [&](PlaceVerdict verdict, const LocatorOptions& options) {
    const bool accepted = JudgeViewAgain(photo_, place_, keyframes_, options, &verdict);
    return !accepted && !verdict.accepted && verdict.agreement.samples == 0;
  };
  PlaceVerdict refused_elsewhere = verdict_;
  refused_elsewhere.passed_other_checks = false;  // too few cells, say
  EXPECT_TRUE(unchanged(refused_elsewhere, options_));
  PlaceVerdict on_ceiling = verdict_;
  on_ceiling.ceiling_only = true;
  EXPECT_TRUE(unchanged(on_ceiling, options_));
  LocatorOptions off = options_;
  off.view_second_opinion.keyframes = 0;
  EXPECT_TRUE(unchanged(verdict_, off));
  // No other keyframe near the pose: the verified keyframe's judgement stands.
  Place alone = place_;
  alone.slots = {0, 2, 3, 4};
  PlaceVerdict verdict = verdict_;
  EXPECT_FALSE(JudgeViewAgain(photo_, alone, keyframes_, options_, &verdict));
  EXPECT_FALSE(verdict.accepted);
  // A pose half a metre off stays refused with both keyframes.
  verdict = verdict_;
  verdict.pose.world_from_cam = PoseAt({0.5, 0, 0}, 0);
  EXPECT_FALSE(JudgeViewAgain(photo_, place_, keyframes_, options_, &verdict));
  EXPECT_FALSE(verdict.accepted);
  EXPECT_TRUE(verdict.looks_different);
}

TEST_F(JudgeViewAgainTest, OptionsThatCannotWorkAreRefused) {
  EXPECT_TRUE(options_.Check(nullptr));
  for (const auto& spoil : std::vector<std::function<void(LocatorOptions*)>>{
           [](LocatorOptions* o) { o->view_second_opinion.keyframes = -1; },
           [](LocatorOptions* o) { o->view_second_opinion.radius_m = 0.0; },
           [](LocatorOptions* o) { o->view_second_opinion.max_angle_deg = 0.0; },
           [](LocatorOptions* o) { o->view_second_opinion.max_angle_deg = 181.0; }}) {
    LocatorOptions options = options_;
    spoil(&options);
    std::string error;
    EXPECT_FALSE(options.Check(&error));
    EXPECT_NE(error.find("view_second_opinion"), std::string::npos) << error;
  }
}

TEST_F(JudgeViewAgainTest, PosesAreJudgedAgainOnlyWhenNoneWasAccepted) {
  PlaceVerdict accepted_elsewhere;
  accepted_elsewhere.accepted = true;
  std::vector<PlaceVerdict> verdicts = {verdict_, accepted_elsewhere};
  const std::vector<Place> places = {place_, place_};
  JudgeViewsAgain(photo_, places, keyframes_, options_, &verdicts);
  EXPECT_FALSE(verdicts[0].accepted);
  EXPECT_TRUE(verdicts[0].looks_different);
  verdicts = {verdict_, PlaceVerdict()};
  JudgeViewsAgain(photo_, places, keyframes_, options_, &verdicts);
  EXPECT_TRUE(verdicts[0].accepted);
  EXPECT_FALSE(verdicts[1].accepted);
}

}  // namespace
}  // namespace sightmap::identify
