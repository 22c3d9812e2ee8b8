// The Locator against a model built from the simulator's walk with ground-truth poses, and the
// visibility test on hand-built scenes.
#include "identify/locator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <random>
#include <thread>
#include <utility>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "identify/exif_testing.h"
#include "identify/sim_model_testing.h"
#include "identify/visibility.h"
#include "sim/simulator.h"

namespace sightmap::identify {
namespace {

namespace fs = std::filesystem;

double PositionError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

// A matched photo's pose must be right: within 0.5 m and 10 degrees of the truth.
void ExpectRightPose(const LocateResult& result, const sim::QueryPhoto& photo) {
  EXPECT_LT(PositionError(result.world_from_cam, photo.world_from_cam), 0.5) << photo.index;
  EXPECT_LT(RotationAngleDeg(result.world_from_cam.linear(), photo.world_from_cam.linear()), 10.0)
      << photo.index;
}

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0.0 : values[values.size() / 2];
}

// One model for the whole suite: 100 s of the office walk (session 1) at 1 Hz, ground-truth
// poses, every appliance labelled; and session-2 phone photos of the places that walk saw.
class LocatorTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("sightmap-locator-test-" + std::to_string(::getpid())));
    fs::create_directories(*dir_);
    SimModelOptions options;
    options.keyframes = 100;
    summary_ = new SimModelSummary(BuildSimulatorModel((*dir_ / "model.db").string(), options));
    model_ = new store::Model(store::Model::Open((*dir_ / "model.db").string()));
    locator_ = new Locator(*model_);

    // Session 2: other lighting, chairs moved. Photos whose camera stands within 1.5 m of a
    // keyframe and looks within 40 deg of its direction show a place the walk saw.
    sim::Simulator simulator(PhotoSessionOptions());
    sim::QueryOptions query_options;
    std::vector<sim::QueryPhoto> photos = simulator.MakeQueries(200, query_options);
    seen_photos_ = new std::vector<sim::QueryPhoto>();
    for (sim::QueryPhoto& photo : photos) {
      if (WalkSawPlace(summary_->world_from_cam, photo.world_from_cam)) {
        seen_photos_->push_back(std::move(photo));
      }
    }
    scene_ = new sim::Scene(simulator.scene());
  }

  static void TearDownTestSuite() {
    delete locator_;
    delete model_;
    delete summary_;
    delete seen_photos_;
    delete scene_;
    std::error_code ignored;
    fs::remove_all(*dir_, ignored);
    delete dir_;
  }

  static fs::path* dir_;
  static SimModelSummary* summary_;
  static store::Model* model_;
  static Locator* locator_;
  static std::vector<sim::QueryPhoto>* seen_photos_;
  static sim::Scene* scene_;
};

fs::path* LocatorTest::dir_ = nullptr;
SimModelSummary* LocatorTest::summary_ = nullptr;
store::Model* LocatorTest::model_ = nullptr;
Locator* LocatorTest::locator_ = nullptr;
std::vector<sim::QueryPhoto>* LocatorTest::seen_photos_ = nullptr;
sim::Scene* LocatorTest::scene_ = nullptr;

TEST_F(LocatorTest, LoadsEveryKeyframeAndAnOcclusionCloud) {
  EXPECT_EQ(locator_->NumKeyframes(), 100u);
  EXPECT_GT(locator_->NumOcclusionVoxels(), 10000u);
  EXPECT_EQ(locator_->Labels().size(), scene_->appliances.size());
}

TEST_F(LocatorTest, LoadingOnOneThreadGivesTheSameLocatorAsOnTwo) {
  // The suite's locator loaded its keyframes on two threads (two connections, two clouds merged);
  // with OpenCV held to one thread it loads them on the calling one.
  if (cv::getNumThreads() < 2) GTEST_SKIP() << "OpenCV has one thread here: nothing to compare";
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  const Locator one_thread(*model_);
  cv::setNumThreads(threads);
  EXPECT_EQ(one_thread.NumKeyframes(), locator_->NumKeyframes());
  EXPECT_EQ(one_thread.NumOcclusionVoxels(), locator_->NumOcclusionVoxels());
  ASSERT_FALSE(seen_photos_->empty());
  int compared = 0;
  for (size_t i = 0; i < seen_photos_->size() && compared < 3; ++i) {
    const sim::QueryPhoto& photo = (*seen_photos_)[i];
    const LocateResult a = locator_->Locate(photo.image, photo.intrinsics);
    const LocateResult b = one_thread.Locate(photo.image, photo.intrinsics);
    ASSERT_EQ(a.matched, b.matched) << "photo " << photo.index;
    if (!a.matched) continue;
    ++compared;
    EXPECT_EQ(a.inliers, b.inliers) << "photo " << photo.index;
    EXPECT_EQ(a.keyframe, b.keyframe) << "photo " << photo.index;
    EXPECT_LT(PositionError(a.world_from_cam, b.world_from_cam), 1e-9) << "photo " << photo.index;
    ASSERT_EQ(a.appliances.size(), b.appliances.size()) << "photo " << photo.index;
    for (size_t k = 0; k < a.appliances.size(); ++k) {
      EXPECT_EQ(a.appliances[k].name, b.appliances[k].name);
      EXPECT_EQ(a.appliances[k].occluded, b.appliances[k].occluded);
    }
  }
  EXPECT_EQ(compared, 3);
}

TEST_F(LocatorTest, LoadingReportsItsProgressOnTheCallingThreadUpToEveryKeyframe) {
  // On one loading thread and on two (the later half read on another thread, which must not call
  // a progress printer that is not thread-safe).
  const int threads = cv::getNumThreads();
  for (const int loading_threads : {1, threads}) {
    cv::setNumThreads(loading_threads);
    std::vector<std::pair<size_t, size_t>> calls;
    const std::thread::id caller = std::this_thread::get_id();
    bool called_elsewhere = false;
    const Locator loaded(*model_, LocatorOptions(), [&](size_t done, size_t total) {
      called_elsewhere = called_elsewhere || std::this_thread::get_id() != caller;
      calls.emplace_back(done, total);
    });
    cv::setNumThreads(threads);
    const size_t keyframes = loaded.NumKeyframes();
    ASSERT_GT(keyframes, 10u);
    EXPECT_FALSE(called_elsewhere) << loading_threads << " loading threads";
    // At least one call per keyframe the calling thread read, the count never going back, the
    // last one the whole model.
    ASSERT_GE(calls.size(), loading_threads == 1 ? keyframes : keyframes / 2);
    for (size_t i = 0; i < calls.size(); ++i) {
      EXPECT_EQ(calls[i].second, keyframes);
      EXPECT_LE(calls[i].first, keyframes);
      if (i > 0) {
        EXPECT_GE(calls[i].first, calls[i - 1].first);
      }
    }
    EXPECT_EQ(calls.back().first, keyframes) << loading_threads << " loading threads";
  }
}

TEST_F(LocatorTest, SessionTwoPhotosOfSeenPlacesAreMatchedWithinCentimetres) {
  ASSERT_GE(seen_photos_->size(), 12u) << "too few session-2 photos of places the walk saw";
  std::vector<double> position_errors;
  std::vector<double> rotation_errors;
  int matched = 0;
  int accurate = 0;  // within 5 cm and 2 deg
  int judged = 0;    // matched photos the view check could judge
  int refused = 0;   // not matched, with a pose the checks refused
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult result = locator_->Locate(photo.image, photo.intrinsics);
    // A refused pose comes with its inliers, and only with a refusal.
    EXPECT_EQ(result.refused_world_from_cam.has_value(), result.refused_inliers > 0);
    if (!result.matched) {
      std::printf("photo %d not matched: %s\n", photo.index, result.reason.c_str());
      if (result.refused_world_from_cam) {
        ++refused;
        std::printf("  its best refused pose: %d inliers, %.2f m off\n", result.refused_inliers,
                    PositionError(*result.refused_world_from_cam, photo.world_from_cam));
      }
      continue;
    }
    ++matched;
    EXPECT_EQ(result.intrinsics_source, IntrinsicsSource::kGiven);
    // A right pose lines up the keyframe's pixels with the photo's.
    if (result.view_agreement) {
      ++judged;
      EXPECT_GE(*result.view_agreement, locator_->options().min_view_agreement);
    }
    position_errors.push_back(PositionError(result.world_from_cam, photo.world_from_cam));
    rotation_errors.push_back(
        RotationAngleDeg(result.world_from_cam.linear(), photo.world_from_cam.linear()));
    if (position_errors.back() <= 0.05 && rotation_errors.back() <= 2.0) ++accurate;
  }
  std::printf(
      "matched %d of %zu; position error median %.1f mm max %.1f mm; rotation median "
      "%.2f deg max %.2f deg\n",
      matched, seen_photos_->size(), 1e3 * Median(position_errors),
      1e3 * *std::max_element(position_errors.begin(), position_errors.end()),
      Median(rotation_errors), *std::max_element(rotation_errors.begin(), rotation_errors.end()));
  // Measured (100 keyframes, the 33 of 200 photos that show a seen place; the scene's tiled
  // ceilings, overhead appliances photographed level-ish): 21 matched (ORB alone: 16-17), median
  // 8 mm / 0.15 deg, the worst 443 mm / 3.8 deg. The bounds say what holds today with a margin of
  // three photos, not the goal (95% matched); no verified pose may be wrong (0.5 m or
  // 10 deg).
  EXPECT_GE(matched, static_cast<int>(0.54 * static_cast<double>(seen_photos_->size())));
  EXPECT_GE(accurate, static_cast<int>(0.8 * matched));
  for (size_t i = 0; i < position_errors.size(); ++i) {
    EXPECT_LT(position_errors[i], 0.5);
    EXPECT_LT(rotation_errors[i], 10.0);
  }
  EXPECT_LE(Median(position_errors), 0.01);
  EXPECT_LE(Median(rotation_errors), 0.3);
  // The view check ran on the keyframes' thumbnails: most matched photos overlap their keyframe.
  EXPECT_GE(judged, matched * 3 / 4) << judged << " of " << matched << " judged";
  EXPECT_GE(refused, 1);
}

TEST_F(LocatorTest, MatchingBoundedByVocabularyNodesStillMatchesMostSeenPhotos) {
  LocatorOptions options;
  options.match_node_level = 2;
  const Locator bounded(*model_, options);
  int matched = 0;
  std::vector<double> position_errors;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult result = bounded.Locate(photo.image, photo.intrinsics);
    if (!result.matched) continue;
    ++matched;
    position_errors.push_back(PositionError(result.world_from_cam, photo.world_from_cam));
  }
  // Measured: 15 of 33 (exhaustive matching: 16); on an earlier draw one of them was 2.6 m off
  // (why it is not the default); the median stays at millimetres.
  EXPECT_GE(matched, static_cast<int>(0.40 * static_cast<double>(seen_photos_->size())));
  ASSERT_FALSE(position_errors.empty());
  EXPECT_LE(Median(position_errors), 0.01);
}

// Places matched and verified several at once give the answers one at a time gives: verdicts
// count in order up to the first certain one, whatever finishes first. RootSIFT extracted ahead,
// on another thread while ORB searches, gives the second look's answers as extracted after it.
TEST_F(LocatorTest, PlacesVerifiedOnThreadsGiveTheSameAnswers) {
  LocatorOptions serial_options;
  serial_options.place_threads = 1;
  serial_options.extract_sift_ahead = false;
  LocatorOptions threaded_options = serial_options;
  threaded_options.place_threads = 3;
  threaded_options.extract_sift_ahead = true;
  const Locator serial(*model_, serial_options);
  const Locator threaded(*model_, threaded_options);
  int several_places = 0;
  int second_looks = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult one = serial.Locate(photo.image, photo.intrinsics);
    const LocateResult three = threaded.Locate(photo.image, photo.intrinsics);
    EXPECT_EQ(one.matched, three.matched) << photo.index;
    EXPECT_EQ(one.reason, three.reason) << photo.index;
    EXPECT_EQ(one.candidates_tried, three.candidates_tried) << photo.index;
    EXPECT_EQ(one.inliers, three.inliers) << photo.index;
    EXPECT_EQ(one.runner_up_inliers, three.runner_up_inliers) << photo.index;
    EXPECT_EQ(one.keyframe, three.keyframe) << photo.index;
    EXPECT_EQ(one.second_look, three.second_look) << photo.index;
    EXPECT_EQ(one.answered_by_second_look, three.answered_by_second_look) << photo.index;
    EXPECT_LT((one.world_from_cam.matrix() - three.world_from_cam.matrix()).norm(), 1e-9)
        << photo.index;
    several_places += one.candidates_tried > 2 ? 1 : 0;
    second_looks += three.second_look ? 1 : 0;
  }
  EXPECT_GE(several_places, 3);  // the threads had places to share
  EXPECT_GE(second_looks, 3);    // and RootSIFT was extracted ahead
}

// The default matcher gives RootSIFT a second look at what ORB could not place: it places at
// least what ORB alone places and more, none of them wrong; RootSIFT alone places photos too. The
// fixture's model stores every keyframe's RootSIFT, so none is extracted at load.
TEST_F(LocatorTest, RootSiftPlacesPhotosOrbCouldNotAndNoneWrong) {
  LocatorOptions orb_only;
  orb_only.matcher = LocatorOptions::Matcher::kOrb;
  const Locator orb(*model_, orb_only);
  LocatorOptions sift_only;
  sift_only.matcher = LocatorOptions::Matcher::kRootSift;
  const Locator sift(*model_, sift_only);
  EXPECT_EQ(orb.NumSiftExtractedAtLoad(), 0u);
  EXPECT_TRUE(orb.LoadWarning().empty());
  EXPECT_EQ(locator_->NumSiftExtractedAtLoad(), 0u);  // stored, as `sightmap map` stores them
  EXPECT_TRUE(locator_->LoadWarning().empty()) << locator_->LoadWarning();
  int by_orb = 0;
  int by_default = 0;
  int by_sift = 0;
  int only_by_default = 0;
  int ambiguous = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult first = orb.Locate(photo.image, photo.intrinsics);
    const LocateResult both = locator_->Locate(photo.image, photo.intrinsics);
    const LocateResult alone = sift.Locate(photo.image, photo.intrinsics);
    for (const LocateResult* result : {&first, &both, &alone}) {
      if (result->matched) ExpectRightPose(*result, photo);
      // An ambiguous answer names the two places that fit; no other answer names any.
      if (result->reason_code != UnmatchedReason::kAmbiguous) {
        EXPECT_TRUE(result->possible_places.empty()) << photo.index;
        continue;
      }
      ++ambiguous;
      ASSERT_EQ(result->possible_places.size(), 2u) << photo.index;
      const PossiblePlace& would_be = result->possible_places[0];
      const PossiblePlace& other = result->possible_places[1];
      EXPECT_GE(std::min(would_be.inliers, other.inliers), LocatorOptions().min_inliers)
          << photo.index;
      EXPECT_GT(
          (would_be.world_from_cam.translation() - other.world_from_cam.translation()).norm() +
              RotationAngleDeg(would_be.world_from_cam.linear(), other.world_from_cam.linear()),
          0.0)
          << photo.index;
      EXPECT_TRUE(would_be.keyframe.valid() && other.keyframe.valid()) << photo.index;
    }
    // ORB's answer stands whenever it places the photo.
    if (first.matched) {
      ASSERT_TRUE(both.matched) << photo.index;
      EXPECT_EQ(both.keyframe, first.keyframe) << photo.index;
      EXPECT_EQ(both.inliers, first.inliers) << photo.index;
      EXPECT_FALSE(both.second_look) << photo.index;
      EXPECT_EQ(both.timings.second_look_ms, 0.0) << photo.index;
    } else if (first.reason_code != UnmatchedReason::kAmbiguous) {
      // Photos ORB gave features for but could not place get the second look; a RootSIFT
      // answer is a pose or "ambiguous".
      EXPECT_TRUE(both.second_look) << photo.index;
      EXPECT_EQ(both.answered_by_second_look,
                both.matched || both.reason_code == UnmatchedReason::kAmbiguous)
          << photo.index;
      EXPECT_GT(both.timings.second_look_ms, 0.0) << photo.index;
      EXPECT_LE(both.timings.second_look_ms, both.timings.total_ms) << photo.index;
    }
    EXPECT_FALSE(first.second_look || alone.second_look) << photo.index;
    by_orb += first.matched ? 1 : 0;
    by_default += both.matched ? 1 : 0;
    by_sift += alone.matched ? 1 : 0;
    only_by_default += both.matched && !first.matched ? 1 : 0;
  }
  std::printf(
      "of %zu seen photos: ORB %d, ORB then RootSIFT %d, RootSIFT %d; %d answers "
      "ambiguous\n",
      seen_photos_->size(), by_orb, by_default, by_sift, ambiguous);
  EXPECT_GE(only_by_default, 2);  // measured 3 (20 -> 23 of 32)
  EXPECT_GE(by_sift, static_cast<int>(0.40 * static_cast<double>(seen_photos_->size())));
}

// A photo placed nowhere is searched again from votes over a wider shortlist
// (wide_vote_shortlist): a narrow retrieval (the bag of words' best 2, one place) misses places
// the votes over every keyframe rank first. The retry's answers are right, and a photo the first
// search answered keeps its answer and is not searched again.
TEST_F(LocatorTest, APhotoPlacedNowhereIsSearchedAgainFromAWiderShortlist) {
  LocatorOptions narrow;
  narrow.retrieval_candidates = 2;
  narrow.reserve_candidates = 0;
  narrow.vote_shortlist = 2;
  narrow.max_places = 1;
  narrow.matcher = LocatorOptions::Matcher::kOrb;
  LocatorOptions wide = narrow;
  wide.wide_vote_shortlist = 1000;
  const Locator first(*model_, narrow);
  const Locator again(*model_, wide);
  int retried = 0;
  int placed_by_retry = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult before = first.Locate(photo.image, photo.intrinsics);
    const LocateResult after = again.Locate(photo.image, photo.intrinsics);
    EXPECT_FALSE(before.wide_retrieval || before.answered_by_wide_retrieval) << photo.index;
    if (after.matched) ExpectRightPose(after, photo);
    if (before.matched || before.reason_code == UnmatchedReason::kAmbiguous) {
      EXPECT_FALSE(after.wide_retrieval) << photo.index;
      EXPECT_EQ(after.matched, before.matched) << photo.index;
      EXPECT_EQ(after.keyframe, before.keyframe) << photo.index;
      EXPECT_EQ(after.inliers, before.inliers) << photo.index;
      continue;
    }
    retried += after.wide_retrieval ? 1 : 0;
    EXPECT_EQ(after.answered_by_wide_retrieval,
              after.matched || after.reason_code == UnmatchedReason::kAmbiguous)
        << photo.index;
    EXPECT_TRUE(after.wide_retrieval || !after.answered_by_wide_retrieval) << photo.index;
    placed_by_retry += after.matched ? 1 : 0;
  }
  std::printf("of %zu seen photos: %d searched again, %d of them placed\n", seen_photos_->size(),
              retried, placed_by_retry);
  EXPECT_GE(placed_by_retry, 2);
  LocatorOptions bad;
  std::string error;
  for (const int shortlist : {-1, bad.vote_shortlist}) {
    bad.wide_vote_shortlist = shortlist;
    EXPECT_FALSE(bad.Check(&error)) << shortlist;
    EXPECT_NE(error.find("wide_vote_shortlist"), std::string::npos) << error;
  }
}

// A pose RootSIFT's second look found must pass the view check (second_look_min_inliers_unchecked
// defaults to every pose): with a check that can never judge, ORB's answers of
// min_inliers_unchecked inliers and more stand and the second look places nothing, unless
// second_look_min_inliers_unchecked lets such poses through.
TEST_F(LocatorTest, SecondLookPosesTheViewCheckCannotJudgeAreRefused) {
  LocatorOptions blind;
  blind.view_agreement.min_samples = 1 << 30;
  const Locator strict(*model_, blind);
  blind.second_look_min_inliers_unchecked = 0;
  const Locator lenient(*model_, blind);
  int by_first = 0;
  int by_second_look = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult refused = strict.Locate(photo.image, photo.intrinsics);
    const LocateResult let_through = lenient.Locate(photo.image, photo.intrinsics);
    EXPECT_FALSE(refused.view_agreement.has_value()) << photo.index;
    EXPECT_FALSE(refused.matched && refused.answered_by_second_look) << photo.index;
    if (refused.matched) {
      EXPECT_GE(refused.inliers, blind.min_inliers_unchecked) << photo.index;
      EXPECT_EQ(let_through.keyframe, refused.keyframe) << photo.index;
      ++by_first;
    }
    if (!let_through.second_look) {
      EXPECT_EQ(let_through.matched, refused.matched) << photo.index;
    }
    by_second_look += let_through.matched && let_through.answered_by_second_look ? 1 : 0;
  }
  std::printf(
      "of %zu seen photos, the view check never judging: %d placed by ORB, %d more by "
      "RootSIFT when its unjudged poses are let through\n",
      seen_photos_->size(), by_first, by_second_look);
  EXPECT_GE(by_first, 1);
  EXPECT_GE(by_second_look, 1);
}

// VLAD's look-alikes tried first by the second look (second_look_retrieval vlad): ORB's answers
// stand, the photos ORB could not place get the second look as before, and what it places is
// right.
TEST_F(LocatorTest, VladLookAlikesFirstLeaveOrbsAnswersAndPlaceNothingWrong) {
  LocatorOptions vlad_first;
  vlad_first.second_look_retrieval = LocatorOptions::SecondLookRetrieval::kVlad;
  const Locator vlad(*model_, vlad_first);
  LocatorOptions orb_first;
  orb_first.second_look_retrieval = LocatorOptions::SecondLookRetrieval::kOrb;
  const Locator orb(*model_, orb_first);
  int by_orb = 0;
  int by_vlad = 0;
  int second_looks = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult before = orb.Locate(photo.image, photo.intrinsics);
    const LocateResult after = vlad.Locate(photo.image, photo.intrinsics);
    EXPECT_EQ(after.second_look, before.second_look) << photo.index;
    if (!before.second_look) {
      EXPECT_EQ(after.matched, before.matched) << photo.index;
      EXPECT_EQ(after.keyframe, before.keyframe) << photo.index;
      EXPECT_EQ(after.inliers, before.inliers) << photo.index;
    }
    if (after.matched) ExpectRightPose(after, photo);
    by_orb += before.matched ? 1 : 0;
    by_vlad += after.matched ? 1 : 0;
    second_looks += after.second_look ? 1 : 0;
  }
  std::printf(
      "of %zu seen photos: %d second looks; placed %d with ORB's candidates, %d VLAD's first\n",
      seen_photos_->size(), second_looks, by_orb, by_vlad);
  EXPECT_GE(second_looks, 3);
  EXPECT_GE(by_vlad, by_orb - 1);
}

TEST_F(LocatorTest, NoiseAndABlankWallAreNotMatchedAndSayWhy) {
  cv::Mat noise(960, 1280, CV_8UC3);
  cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
  const Intrinsics phone = sim::QueryOptions().PhoneIntrinsics();
  const LocateResult noisy = locator_->Locate(noise, phone);
  EXPECT_FALSE(noisy.matched);
  EXPECT_FALSE(noisy.reason.empty());
  EXPECT_NE(noisy.reason_code, UnmatchedReason::kNone);
  std::printf("noise: %s (%s)\n", noisy.reason.c_str(), ToString(noisy.reason_code));

  const cv::Mat blank(960, 1280, CV_8UC3, cv::Scalar(200, 205, 210));
  const LocateResult wall = locator_->Locate(blank, std::nullopt);
  EXPECT_FALSE(wall.matched);
  EXPECT_NE(wall.reason.find("features"), std::string::npos) << wall.reason;
  EXPECT_EQ(wall.reason_code, UnmatchedReason::kFewFeatures);
  EXPECT_NE(std::string(Advice(wall.reason_code)).find("too little detail"), std::string::npos);
  EXPECT_EQ(wall.intrinsics_source, IntrinsicsSource::kEstimated);
  EXPECT_TRUE(wall.appliances.empty());

  const LocateResult empty = locator_->Locate(cv::Mat(), phone);
  EXPECT_FALSE(empty.matched);
  EXPECT_EQ(empty.reason_code, UnmatchedReason::kEmptyPhoto);

  // Pixels too few for ORB's pyramid (which threw on a 1-px side), given directly or left so by
  // downscaling a long thin photo: not matched, and said why.
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(1000, 1), cv::Size(64, 20000)}) {
    const LocateResult thin =
        locator_->Locate(cv::Mat(size, CV_8UC3, cv::Scalar(1, 2, 3)), std::nullopt);
    EXPECT_FALSE(thin.matched) << size;
    EXPECT_EQ(thin.reason_code, UnmatchedReason::kFewFeatures) << size;
    EXPECT_NE(thin.reason.find("too small or too narrow"), std::string::npos) << thin.reason;
  }
}

// A photo of the walk's place with all but its top-left quarter painted over (a bare ceiling
// round a light): not matched, answered as a bare view with the advice to include more. The
// whole photo it came from keeps its own answer.
TEST_F(LocatorTest, ABareViewIsAnsweredInWords) {
  ASSERT_FALSE(seen_photos_->empty());
  int bare_answers = 0;
  int tried = 0;
  for (size_t i = 0; i < seen_photos_->size() && tried < 4; ++i) {
    const sim::QueryPhoto& photo = (*seen_photos_)[i];
    // Photos with detail all over (some photos of seen places are bare themselves: a light on
    // the ceiling grid, a switch on a wall).
    const LocateResult whole = locator_->Locate(photo.image, photo.intrinsics);
    if (whole.photo_detail_cells <= 3) continue;
    ++tried;
    EXPECT_NE(whole.reason_code, UnmatchedReason::kBareView) << "photo " << photo.index;
    cv::Mat bare(photo.image.size(), photo.image.type(), cv::Scalar(200, 202, 205));
    const cv::Rect corner(0, 0, photo.image.cols / 4, photo.image.rows / 4);
    photo.image(corner).copyTo(bare(corner));
    const LocateResult answer = locator_->Locate(bare, photo.intrinsics);
    EXPECT_LE(answer.photo_detail_cells, 1) << "photo " << photo.index;
    EXPECT_FALSE(answer.matched) << "photo " << photo.index;
    if (answer.reason_code == UnmatchedReason::kFewFeatures) continue;  // nothing in the corner
    ++bare_answers;
    EXPECT_EQ(answer.reason_code, UnmatchedReason::kBareView) << answer.reason;
    EXPECT_NE(answer.reason.find("little detail"), std::string::npos) << answer.reason;
    EXPECT_STREQ(Advice(answer.reason_code),
                 "Too little detail: include a wall or furniture in the photo.");
    EXPECT_EQ(ToJson(answer)["reason_code"], "bare_view");
  }
  EXPECT_EQ(tried, 4);
  EXPECT_GE(bare_answers, 1);
}

TEST_F(LocatorTest, EstimatedIntrinsicsLandNearTheTrueFocal) {
  int tried = 0;
  int ambiguous = 0;
  int bare = 0;
  std::vector<double> focal_errors;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    if (tried == 4) break;
    const LocateResult given = locator_->Locate(photo.image, photo.intrinsics);
    if (!given.matched) continue;
    const LocateResult estimated = locator_->Locate(photo.image, std::nullopt);
    // A free focal length lets a pose slide along the view: photo 33 fits 0.9 m away as well
    // with another focal (19% off, 1.2 m from the truth), and is refused as ambiguous rather
    // than answered there. A bare photo (photo 17: a ceiling light, ORB features in 2 of 16
    // cells) that RootSIFT places with the true focal may fall short of the inlier cells with a
    // guessed one, and is then answered as bare. Any other refusal is a failure.
    if (!estimated.matched) {
      if (estimated.reason_code == UnmatchedReason::kBareView) {
        EXPECT_LE(given.photo_detail_cells, LocatorOptions().bare_view_max_detail_cells)
            << "photo " << photo.index << ": " << estimated.reason;
        ++bare;
        continue;
      }
      EXPECT_EQ(estimated.reason_code, UnmatchedReason::kAmbiguous)
          << "photo " << photo.index << ": " << estimated.reason;
      ++ambiguous;
      continue;
    }
    ++tried;
    EXPECT_EQ(estimated.intrinsics_source, IntrinsicsSource::kEstimated);
    const double focal_error = std::abs(estimated.intrinsics.fx / photo.intrinsics.fx - 1.0);
    std::printf("photo %d: estimated fx %.1f, true %.1f (%.1f%%), position error %.1f mm\n",
                photo.index, estimated.intrinsics.fx, photo.intrinsics.fx, 100 * focal_error,
                1e3 * PositionError(estimated.world_from_cam, photo.world_from_cam));
    focal_errors.push_back(focal_error);
    EXPECT_NEAR(estimated.intrinsics.cx, (photo.image.cols - 1) / 2.0, 1e-9);
  }
  EXPECT_EQ(tried, 4);
  EXPECT_LE(ambiguous, 1);
  EXPECT_LE(bare, 1);
  // Measured with the defaults (960 px, 1500 features): 0.5%, 3.5%, 13.5% and 30% (a shallow view
  // where 35 mm fits as well as the true 27 mm); with 1280 px and 2000 features 1.7-4.0%. Only
  // half of them are held to 5% until the focal search is made robust.
  EXPECT_GE(
      std::count_if(focal_errors.begin(), focal_errors.end(), [](double e) { return e <= 0.05; }),
      2);
}

TEST_F(LocatorTest, LargePhotosAreDownscaledAndAnswerInTheirOwnPixels) {
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult small = locator_->Locate(photo.image, photo.intrinsics);
    if (!small.matched || small.appliances.empty()) continue;
    cv::Mat large;
    cv::resize(photo.image, large, cv::Size(2560, 1920), 0, 0, cv::INTER_LINEAR);
    const LocateResult result = locator_->Locate(large, photo.intrinsics.Scaled(2560, 1920));
    ASSERT_TRUE(result.matched) << result.reason;
    EXPECT_EQ(result.intrinsics.width, 2560);
    EXPECT_LE(PositionError(result.world_from_cam, photo.world_from_cam), 0.05);
    ASSERT_FALSE(result.appliances.empty());
    EXPECT_NEAR(result.appliances[0].pixel.x(), 2.0 * small.appliances[0].pixel.x() + 0.5, 6.0);
    return;
  }
  FAIL() << "no matched photo with an appliance in view";
}

// Against the simulator's ground truth: what is reported visible is really there, and occluded
// instances are not reported as visible.
// A phone held upright stores its pixels sideways and says so in EXIF (orientation 6: turn a
// quarter clockwise to show). Located through the one photo path, with the sensor's (landscape)
// calibration or the upright intrinsics, it must land where the upright photo does.
TEST_F(LocatorTest, APortraitPhotoStoredSidewaysLandsWhereTheUprightOneDoes) {
  // A photo as a phone stores it: JPEG, with an EXIF orientation.
  const auto as_stored = [](const cv::Mat& pixels, const testing::ExifFields& fields) {
    const std::vector<uint8_t> jpeg = testing::JpegWithExif(pixels, fields);
    return DecodePhoto(jpeg.data(), jpeg.size(), kMaxPhotoMegapixels);
  };
  int compared = 0;
  for (const sim::QueryPhoto& query : *seen_photos_) {
    IntrinsicsHint given;
    given.upright = query.intrinsics;
    // The upright photo is stored as a JPEG too, so that what is compared is the orientation
    // alone: JPEG at quality 95 alone took one photo from 421 inliers to none (measured with
    // anisotropic texture filtering, tried in the simulator and not kept). One matched without
    // margin could fall under the bar either way up.
    const LocateResult upright = locator_->Locate(as_stored(query.image, {}), given);
    if (!upright.matched || upright.inliers < 2 * LocatorOptions().min_inliers) continue;
    cv::Mat sideways;
    cv::rotate(query.image, sideways, cv::ROTATE_90_COUNTERCLOCKWISE);
    testing::ExifFields fields;
    fields.orientation = 6;
    const Photo photo = as_stored(sideways, fields);
    ASSERT_EQ(photo.width(), query.image.cols);
    ASSERT_EQ(photo.height(), query.image.rows);

    IntrinsicsHint from_calibration;
    from_calibration.sensor = TurnClockwise(query.intrinsics, 3);  // the sideways sensor's
    for (const IntrinsicsHint& hint : {from_calibration, given}) {
      const LocateResult result = locator_->Locate(photo, hint);
      ASSERT_TRUE(result.matched) << "photo " << query.index << ": " << result.reason;
      EXPECT_NEAR(result.intrinsics.fx, query.intrinsics.fx, 1e-9);
      EXPECT_NEAR(result.intrinsics.fy, query.intrinsics.fy, 1e-9);
      EXPECT_NEAR(result.intrinsics.cx, query.intrinsics.cx, 1e-9);
      EXPECT_NEAR(result.intrinsics.cy, query.intrinsics.cy, 1e-9);
      // JPEG compression moves a few features: centimetres, not the metres of a skewed camera.
      EXPECT_LT(PositionError(result.world_from_cam, upright.world_from_cam), 0.03);
      EXPECT_LT(RotationAngleDeg(result.world_from_cam.linear(), upright.world_from_cam.linear()),
                1.0);
    }
    if (++compared == 3) break;
  }
  EXPECT_EQ(compared, 3);
}

TEST_F(LocatorTest, AppliancesInViewAgreeWithTheGroundTruth) {
  int reported_visible = 0;
  int wrongly_visible = 0;  // reported visible, truth not visible or occluded
  int occluded_truth = 0;
  int occluded_reported_visible = 0;
  int visible_truth = 0;
  int visible_found = 0;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    const LocateResult result = locator_->Locate(photo.image, photo.intrinsics);
    if (!result.matched) continue;
    for (size_t i = 1; i < result.appliances.size(); ++i) {
      EXPECT_LE(result.appliances[i - 1].distance_m, result.appliances[i].distance_m);
    }
    for (const sim::ApplianceVisibility& truth : photo.visibility) {
      const std::string& name =
          scene_->appliances[static_cast<size_t>(truth.appliance_id - 1)].name;
      const auto it = std::find_if(result.appliances.begin(), result.appliances.end(),
                                   [&](const ApplianceInView& a) { return a.name == name; });
      const bool visible = it != result.appliances.end() && !it->occluded;
      if (visible) ++reported_visible;
      if (visible && (truth.type == sim::VisibilityType::kNotVisible ||
                      truth.type == sim::VisibilityType::kOccluded)) {
        ++wrongly_visible;
      }
      if (truth.type == sim::VisibilityType::kOccluded) {
        ++occluded_truth;
        if (visible) ++occluded_reported_visible;
      }
      if (truth.type == sim::VisibilityType::kVisible) {
        ++visible_truth;
        if (visible) ++visible_found;
      }
    }
  }
  std::printf(
      "visible found %d of %d; reported visible %d, wrongly %d; occluded reported visible "
      "%d of %d\n",
      visible_found, visible_truth, reported_visible, wrongly_visible, occluded_reported_visible,
      occluded_truth);
  ASSERT_GT(visible_truth, 0);
  // Measured: 15 of 17 (and 13 of 14 with other defaults); the misses lie at the image border.
  EXPECT_GE(visible_found, 0.8 * visible_truth);
  EXPECT_LE(wrongly_visible, 0.1 * reported_visible);
}

TEST_F(LocatorTest, JsonHasTheDocumentedKeys) {
  const sim::QueryPhoto& photo = seen_photos_->front();
  const nlohmann::json json = ToJson(locator_->Locate(photo.image, photo.intrinsics));
  for (const char* key :
       {"matched", "pose", "inliers", "matches", "keyframe", "intrinsics", "appliances",
        "possible_places", "timings_ms", "second_look", "answered_by_second_look", "wide_retrieval",
        "answered_by_wide_retrieval"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  EXPECT_TRUE(json["possible_places"].empty());  // only an ambiguous photo has them
  ASSERT_TRUE(json["matched"].get<bool>());
  EXPECT_EQ(json["pose"]["world_from_cam"]["position"].size(), 3u);
  EXPECT_EQ(json["pose"]["world_from_cam"]["quaternion_xyzw"].size(), 4u);
  for (const char* key : {"fx", "fy", "cx", "cy", "width", "height", "source"}) {
    EXPECT_TRUE(json["intrinsics"].contains(key)) << key;
  }
  EXPECT_EQ(json["intrinsics"]["source"], "given");
  for (const char* key : {"features", "retrieval", "matching", "pnp", "visibility", "total"}) {
    EXPECT_TRUE(json["timings_ms"].contains(key)) << key;
  }
  for (const nlohmann::json& appliance : json["appliances"]) {
    for (const char* key : {"name", "type", "pixel", "distance_m", "visible", "visible_share"}) {
      EXPECT_TRUE(appliance.contains(key)) << key;
    }
    EXPECT_EQ(appliance["pixel"].size(), 2u);
  }

  const nlohmann::json unmatched = ToJson(locator_->Locate(cv::Mat(), std::nullopt));
  EXPECT_FALSE(unmatched["matched"].get<bool>());
  EXPECT_TRUE(unmatched["reason"].is_string());
  EXPECT_EQ(unmatched["reason_code"], "empty_photo");
  EXPECT_EQ(unmatched["advice"], Advice(UnmatchedReason::kEmptyPhoto));
  EXPECT_EQ(unmatched["intrinsics"]["source"], "estimated");

  // An ambiguous answer names its places, each with what is in view from it.
  LocateResult ambiguous;
  ambiguous.reason_code = UnmatchedReason::kAmbiguous;
  PossiblePlace place;
  place.world_from_cam.translation() = Eigen::Vector3d(1, 2, 3);
  place.inliers = 70;
  place.keyframe = KeyframeId(12);
  place.appliances.push_back({"monitor_2", "monitor", Eigen::Vector2d(40, 50), 1.5, false, 1.0});
  ambiguous.possible_places = {place, place};
  ambiguous.possible_places[1].appliances.clear();
  const nlohmann::json places = ToJson(ambiguous)["possible_places"];
  ASSERT_EQ(places.size(), 2u);
  EXPECT_EQ(places[0]["pose"]["world_from_cam"]["position"], nlohmann::json({1.0, 2.0, 3.0}));
  EXPECT_EQ(places[0]["inliers"], 70);
  EXPECT_EQ(places[0]["keyframe"], 12);
  ASSERT_EQ(places[0]["appliances"].size(), 1u);
  EXPECT_EQ(places[0]["appliances"][0]["name"], "monitor_2");
  EXPECT_TRUE(places[1]["appliances"].empty());
}

// A building whose floors repeat: the walk's first 20 keyframes again, 10 m higher (the floor
// above, every surface alike, none of it labelled). A photo of the walk's place fits both floors
// equally: it is answered ambiguous, naming both places and what is in view from each, so a person
// can tell which it is (here: the labelled floor shows appliances, the copy none).
TEST(LocatorRepeatedFloorTest, AnAmbiguousPhotoNamesBothPlacesAndWhatEachShows) {
  const fs::path dir =
      fs::temp_directory_path() / ("sightmap-locator-floors-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  SimModelOptions model_options;
  model_options.keyframes = 20;
  const SimModelSummary summary = BuildSimulatorModel((dir / "model.db").string(), model_options);
  store::Model model = store::Model::Open((dir / "model.db").string());
  Eigen::Isometry3d floor_above = Eigen::Isometry3d::Identity();
  floor_above.translation() = Eigen::Vector3d(0, 0, 10);
  for (const store::KeyframeInfo& info : model.Keyframes()) {
    store::KeyframeRecord copy;
    copy.session = info.session;
    copy.timestamp_ns = info.timestamp_ns + 1'000'000'000'000;
    copy.world_from_cam = floor_above * info.world_from_cam;
    copy.odom_world_from_cam = floor_above * info.odom_world_from_cam;
    copy.intrinsics = info.intrinsics;
    copy.color = model.LoadColor(info.id);
    copy.depth = model.LoadDepth(info.id);
    copy.features = model.LoadFeatures(info.id);
    copy.photo_features = model.LoadPhotoFeatures(info.id);
    model.AddKeyframe(copy);
  }
  ASSERT_EQ(model.Keyframes().size(), 40u);
  const Locator locator(model);

  // A session-2 photo from where a keyframe stood, of a view with an appliance in it.
  sim::Simulator simulator(PhotoSessionOptions());
  const sim::QueryOptions query_options;
  std::optional<sim::QueryPhoto> photo;
  for (size_t k = 0; k < summary.world_from_cam.size() && !photo; k += 3) {
    sim::QueryPhoto candidate =
        simulator.RenderQuery(query_options.PhoneIntrinsics(), summary.world_from_cam[k],
                              query_options.thresholds, /*noise_seed=*/k);
    if (std::any_of(candidate.visibility.begin(), candidate.visibility.end(),
                    [](const sim::ApplianceVisibility& v) {
                      return v.type == sim::VisibilityType::kVisible;
                    })) {
      photo = std::move(candidate);
    }
  }
  ASSERT_TRUE(photo.has_value()) << "no keyframe of the walk's first 20 s sees an appliance";

  const LocateResult result = locator.Locate(photo->image, photo->intrinsics);
  ASSERT_EQ(result.reason_code, UnmatchedReason::kAmbiguous) << result.reason;
  ASSERT_EQ(result.possible_places.size(), 2u);
  std::vector<double> heights;
  int labelled = -1;
  for (size_t p = 0; p < 2; ++p) {
    const PossiblePlace& place = result.possible_places[p];
    EXPECT_GE(place.inliers, LocatorOptions().min_inliers);
    EXPECT_TRUE(place.keyframe.valid());
    const Eigen::Vector3d offset =
        place.world_from_cam.translation() - photo->world_from_cam.translation();
    heights.push_back(offset.z());
    EXPECT_LT(offset.head<2>().norm(), 0.5) << p;
    const bool shows_any = std::any_of(place.appliances.begin(), place.appliances.end(),
                                       [](const ApplianceInView& a) { return !a.occluded; });
    if (shows_any) labelled = static_cast<int>(p);
  }
  // One on the walk's floor, one 10 m above; appliances in view only from the walk's.
  std::sort(heights.begin(), heights.end());
  EXPECT_LT(std::abs(heights[0]), 0.5);
  EXPECT_LT(std::abs(heights[1] - 10.0), 0.5);
  ASSERT_GE(labelled, 0);
  EXPECT_LT(
      std::abs(
          result.possible_places[static_cast<size_t>(labelled)].world_from_cam.translation().z() -
          photo->world_from_cam.translation().z()),
      0.5);
  const nlohmann::json json = ToJson(result);
  EXPECT_EQ(json["reason_code"], "ambiguous");
  ASSERT_EQ(json["possible_places"].size(), 2u);
  EXPECT_EQ(json["possible_places"][static_cast<size_t>(labelled)]["appliances"].size(),
            result.possible_places[static_cast<size_t>(labelled)].appliances.size());
  std::error_code ignored;
  fs::remove_all(dir, ignored);
}

TEST_F(LocatorTest, ConcurrentCallsGiveTheSameAnswers) {
  // Two photos that match: two unmatched answers (identity poses) would agree whatever happened.
  std::vector<const sim::QueryPhoto*> matching;
  for (const sim::QueryPhoto& photo : *seen_photos_) {
    if (locator_->Locate(photo.image, photo.intrinsics).matched) matching.push_back(&photo);
    if (matching.size() == 2) break;
  }
  ASSERT_EQ(matching.size(), 2u) << "fewer than two seen photos match";
  const sim::QueryPhoto& a = *matching[0];
  const sim::QueryPhoto& b = *matching[1];
  const LocateResult expected_a = locator_->Locate(a.image, a.intrinsics);
  const LocateResult expected_b = locator_->Locate(b.image, b.intrinsics);
  ASSERT_TRUE(expected_a.matched && expected_b.matched);
  LocateResult got_a;
  LocateResult got_b;
  std::thread first([&] { got_a = locator_->Locate(a.image, a.intrinsics); });
  std::thread second([&] { got_b = locator_->Locate(b.image, b.intrinsics); });
  first.join();
  second.join();
  EXPECT_TRUE(got_a.matched);
  EXPECT_TRUE(got_b.matched);
  EXPECT_EQ(got_a.keyframe, expected_a.keyframe);
  EXPECT_EQ(got_b.keyframe, expected_b.keyframe);
  EXPECT_LE(PositionError(got_a.world_from_cam, expected_a.world_from_cam), 0.01);
  EXPECT_LE(PositionError(got_b.world_from_cam, expected_b.world_from_cam), 0.01);
}

TEST(LocatorModelTest, AModelWithoutKeyframesIsAClearError) {
  store::Model empty = store::Model::Open(":memory:");
  try {
    Locator locator(empty);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no keyframes"), std::string::npos) << e.what();
  }
}

// A short recording leaves a model of a few keyframes and no vocabulary (the mapper trains one
// on its first 30): photos must still be located, by a vocabulary trained on what there is, or
// with a single keyframe by trying it.
TEST(LocatorModelTest, AFewKeyframesWithoutAVocabularyStillLocatePhotos) {
  const fs::path dir =
      fs::temp_directory_path() / ("sightmap-locator-small-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const int keyframes : {6, 2}) {
    const std::string path = (dir / ("model-" + std::to_string(keyframes) + ".db")).string();
    SimModelOptions options;
    options.keyframes = keyframes;
    options.write_vocabulary = false;
    options.store_photo_features = false;  // a model mapped before they were stored
    const SimModelSummary summary = BuildSimulatorModel(path, options);
    store::Model model = store::Model::Open(path);
    ASSERT_FALSE(model.LoadVocabulary().has_value());
    // RootSIFT stored for the first keyframe (as `sightmap map` stores it for every one) is read,
    // not extracted again.
    const store::KeyframeInfo first = model.Keyframes().front();
    LocatorOptions defaults;
    model.SetPhotoFeatures(
        first.id, slam::ExtractFeatures(model.LoadColor(first.id), model.LoadDepth(first.id),
                                        first.intrinsics, defaults.sift_features));
    const Locator locator(model);
    EXPECT_EQ(locator.NumKeyframes(), static_cast<size_t>(keyframes));
    EXPECT_EQ(locator.NumSiftExtractedAtLoad(), static_cast<size_t>(keyframes - 1));
    const std::string extracted =
        std::to_string(keyframes - 1) + " of " + std::to_string(keyframes) + " keyframes";
    EXPECT_NE(locator.LoadWarning().find(extracted), std::string::npos) << locator.LoadWarning();
    EXPECT_NE(locator.LoadWarning().find("sightmap info --upgrade"), std::string::npos)
        << locator.LoadWarning();
    // The last keyframe's own view, downscaled: another image of the same place.
    const store::KeyframeInfo info = model.Keyframes().back();
    cv::Mat photo;
    cv::resize(model.LoadColor(info.id), photo, cv::Size(), 0.75, 0.75, cv::INTER_AREA);
    const LocateResult result =
        locator.Locate(photo, info.intrinsics.Scaled(photo.cols, photo.rows));
    ASSERT_TRUE(result.matched) << keyframes << " keyframes: " << result.reason;
    EXPECT_LT(PositionError(result.world_from_cam, summary.world_from_cam.back()), 0.05);
  }
  std::error_code ignored;
  fs::remove_all(dir, ignored);
}

// Hand-built scenes: a camera at the origin looking along +z (the world frame is the camera's).
class VisibilityTest : public ::testing::Test {
 protected:
  VisibilityTest() {
    intrinsics_ = Intrinsics::FromFieldOfView(1280, 960, DegToRad(65.0), 0.0);
    // A wall at z = 3 m across the whole view, sampled finer than its voxels.
    OcclusionCloudBuilder builder(0.05);
    for (double x = -3.0; x <= 3.0; x += 0.02) {
      for (double y = -2.5; y <= 2.5; y += 0.02) builder.AddPoint({x, y, 3.0});
    }
    // A box on the floor in front of the wall: its front face at z = 2 m.
    for (double x = 0.8; x <= 1.2; x += 0.02) {
      for (double y = 0.6; y <= 1.0; y += 0.02) builder.AddPoint({x, y, 2.0});
    }
    cloud_ = builder.Build();
  }

  static store::LabelRecord Label(const std::string& name,
                                  const std::vector<Eigen::Vector3d>& points,
                                  const std::string& type = "lamp") {
    store::LabelRecord label;
    label.name = name;
    label.type = type;
    for (const Eigen::Vector3d& p : points) {
      store::LabelPoint point;
      point.world = p;
      label.points.push_back(point);
    }
    return label;
  }

  Intrinsics intrinsics_;
  OcclusionCloud cloud_;
};

TEST_F(VisibilityTest, BehindTheWallIsOccludedOutsideIsNotListedInPlainViewIsVisible) {
  const std::vector<store::LabelRecord> labels = {
      Label("behind_wall", {{-0.5, 0.2, 4.5}}),
      Label("in_front", {{0.5, -0.3, 1.5}}),
      Label("on_the_wall", {{-1.0, 0.5, 3.0}}),  // sits on the wall: must not hide itself
      // 0.6 m behind the box's face, on the ray through its centre (1.0, 0.8, 2.0).
      Label("behind_the_box", {{1.3, 1.04, 2.6}}),
      Label("outside_the_image", {{10.0, 0.0, 2.0}}),  // 78 deg to the side
      Label("behind_the_camera", {{0.0, 0.0, -2.0}}),
  };
  const std::vector<ApplianceInView> result = AppliancesInView(
      labels, &cloud_, intrinsics_, Eigen::Isometry3d::Identity(), VisibilityOptions());
  ASSERT_EQ(result.size(), 4u);
  // Nearest first.
  EXPECT_EQ(result[0].name, "in_front");
  EXPECT_EQ(result[1].name, "behind_the_box");
  EXPECT_EQ(result[2].name, "on_the_wall");
  EXPECT_EQ(result[3].name, "behind_wall");
  EXPECT_FALSE(result[0].occluded);
  EXPECT_TRUE(result[1].occluded);
  EXPECT_FALSE(result[2].occluded);
  EXPECT_TRUE(result[3].occluded);
  EXPECT_DOUBLE_EQ(result[0].visible_share, 1.0);
  EXPECT_DOUBLE_EQ(result[1].visible_share, 0.0);
  const Eigen::Vector2d expected = intrinsics_.Project({0.5, -0.3, 1.5});
  EXPECT_LE((result[0].pixel - expected).norm(), 1e-6);
  EXPECT_NEAR(result[0].distance_m, Eigen::Vector3d(0.5, -0.3, 1.5).norm(), 1e-9);
  EXPECT_EQ(result[0].type, "lamp");

  // Without a cloud nothing is occluded; the view cone is the same.
  const std::vector<ApplianceInView> bare = AppliancesInView(
      labels, nullptr, intrinsics_, Eigen::Isometry3d::Identity(), VisibilityOptions());
  ASSERT_EQ(bare.size(), 4u);
  for (const ApplianceInView& appliance : bare) EXPECT_FALSE(appliance.occluded);
}

TEST_F(VisibilityTest, AnApplianceCutByThePhotosEdgeIsPartlyInViewAtItsVisiblePoint) {
  const std::vector<store::LabelRecord> labels = {
      Label("half_out", {{0.5, -0.3, 1.5}, {10.0, 0.0, 2.0}}),
      Label("mostly_out", {{0.5, -0.3, 1.5}, {10.0, 0.0, 2.0}, {-10.0, 0.0, 2.0}}),
  };
  const std::vector<ApplianceInView> result = AppliancesInView(
      labels, &cloud_, intrinsics_, Eigen::Isometry3d::Identity(), VisibilityOptions());
  ASSERT_EQ(result.size(), 1u) << "a third in the photo is under min_in_view_share";
  EXPECT_EQ(result[0].name, "half_out");
  EXPECT_FALSE(result[0].occluded);
  EXPECT_DOUBLE_EQ(result[0].visible_share, 0.5);
  EXPECT_LE((result[0].pixel - intrinsics_.Project({0.5, -0.3, 1.5})).norm(), 1e-6);
}

TEST_F(VisibilityTest, APoseMovesTheViewAndPixelsAreTheVisiblePointsCentre) {
  // Turned 180 deg about y and moved behind the wall: the camera at z = 6 looks back along -z,
  // so "behind_wall" at z = 4.5 is now in front of the wall and visible.
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  world_from_cam.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  world_from_cam.translation() = Eigen::Vector3d(0, 0, 6.0);
  const std::vector<store::LabelRecord> labels = {
      Label("two_points", {{-0.5, 0.2, 4.5}, {-0.3, 0.2, 4.5}}),
      Label("in_front_of_origin", {{0.5, -0.3, 1.5}}),
  };
  const std::vector<ApplianceInView> result =
      AppliancesInView(labels, &cloud_, intrinsics_, world_from_cam, VisibilityOptions());
  ASSERT_EQ(result.size(), 2u);
  EXPECT_EQ(result[0].name, "two_points");
  EXPECT_FALSE(result[0].occluded);
  const Eigen::Isometry3d cam_from_world = world_from_cam.inverse();
  const Eigen::Vector2d expected =
      0.5 * (intrinsics_.Project(cam_from_world * Eigen::Vector3d(-0.5, 0.2, 4.5)) +
             intrinsics_.Project(cam_from_world * Eigen::Vector3d(-0.3, 0.2, 4.5)));
  EXPECT_LE((result[0].pixel - expected).norm(), 1e-6);
  EXPECT_TRUE(result[1].occluded);  // now behind the wall
}

TEST_F(VisibilityTest, AFarSwitchSeenFromBehindItsWallIsOccludedWhenTheWalkSawItFromTheFront) {
  // A switch on the near face of a 0.2 m wall (faces z = 3.0 and 3.2 in the cloud), the walk's
  // keyframes in front of it (z < 3) and a photo from 8 m behind the wall, looking back along -z.
  OcclusionCloudBuilder builder(0.05);
  for (double x = -3.0; x <= 3.0; x += 0.02) {
    for (double y = -2.5; y <= 2.5; y += 0.02) {
      builder.AddPoint({x, y, 3.0});
      builder.AddPoint({x, y, 3.2});
    }
  }
  const OcclusionCloud wall = builder.Build();
  const Eigen::Vector3d switch_point(0.3, 0.2, 2.99);
  const std::vector<store::LabelRecord> labels = {Label("switch", {switch_point}, "light_switch")};
  // Keyframes 1.5-2.5 m in front of the wall, looking at it (+z): their depth sees the near face.
  const Intrinsics keyframe_intrinsics = Intrinsics::FromFieldOfView(160, 120, 1.0, 0.0);
  std::vector<SightingView> views;
  for (int i = 0; i < 4; ++i) {
    Eigen::Isometry3d world_from_keyframe = Eigen::Isometry3d::Identity();
    world_from_keyframe.translation() = Eigen::Vector3d(0.4 * i - 0.6, 0.1, 0.5 + 0.3 * i);
    // Facing the wall, every pixel's depth is the distance to its plane z = 3.
    const cv::Mat depth(
        120, 160, CV_16UC1,
        cv::Scalar(std::lround(1000.0 * (3.0 - world_from_keyframe.translation().z()))));
    views.push_back(MakeSightingView(depth, keyframe_intrinsics, world_from_keyframe, 80, 60));
  }
  const VisibilityOptions options;
  const LabelSightings sightings = SightLabels(labels, views, options);
  ASSERT_EQ(sightings.size(), 1u);
  ASSERT_EQ(sightings[0].size(), 1u);
  EXPECT_EQ(sightings[0][0].keyframes, 4);
  EXPECT_GT(sightings[0][0].mean_ray.z(), 0.9);  // seen looking along +z

  Eigen::Isometry3d behind = Eigen::Isometry3d::Identity();
  behind.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  behind.translation() = Eigen::Vector3d(0.0, 0.0, 11.0);
  // The wall's far face is 0.21 m nearer than the switch: inside the 0.15 + 0.05 x 8 m margin.
  const std::vector<ApplianceInView> margin_only =
      AppliancesInView(labels, &wall, intrinsics_, behind, options);
  ASSERT_EQ(margin_only.size(), 1u);
  EXPECT_FALSE(margin_only[0].occluded);
  const std::vector<ApplianceInView> with_sightings =
      AppliancesInView(labels, &wall, intrinsics_, behind, options, &sightings);
  ASSERT_EQ(with_sightings.size(), 1u);
  EXPECT_TRUE(with_sightings[0].occluded);

  // From the front, as far away, it stays visible.
  Eigen::Isometry3d front = Eigen::Isometry3d::Identity();
  front.translation() = Eigen::Vector3d(0.5, 0.0, -5.0);
  const std::vector<ApplianceInView> seen =
      AppliancesInView(labels, &wall, intrinsics_, front, options, &sightings);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_FALSE(seen[0].occluded);
}

TEST_F(VisibilityTest, SeenFromBehindThroughAHoleInItsWallAnApplianceIsHiddenOnItsOwnSurfaceNot) {
  // A 0.2 m wall (faces z = 3.0 and 3.2) with a 1 m square hole round (0, 0) where no keyframe
  // returned depth (a TV's screen, and the wall's far face behind it the walk never came near),
  // the next room's far wall at z = -2 behind it; the walk saw the TV (a label on the near face,
  // inside the hole) and a lamp standing in the open from the front only (looking along +z).
  OcclusionCloudBuilder builder(0.05);
  for (double x = -3.0; x <= 3.0; x += 0.02) {
    for (double y = -2.5; y <= 2.5; y += 0.02) {
      builder.AddPoint({x, y, -2.0});
      if (std::abs(x) < 0.5 && std::abs(y) < 0.5) continue;
      builder.AddPoint({x, y, 3.0});
      builder.AddPoint({x, y, 3.2});
    }
  }
  // The lamp's front face (z = 5.0, x in [1, 1.4]) as the walk saw it; its label clicked on it.
  for (double x = 1.0; x <= 1.4; x += 0.02) {
    for (double y = -0.2; y <= 0.2; y += 0.02) builder.AddPoint({x, y, 5.0});
  }
  const OcclusionCloud cloud = builder.Build();
  const std::vector<store::LabelRecord> labels = {Label("tv", {{0.0, 0.0, 2.98}}),
                                                  Label("lamp", {{1.2, 0.0, 5.0}})};
  LabelSightings sightings(2, std::vector<PointSighting>(1));
  for (std::vector<PointSighting>& label_sightings : sightings) {
    label_sightings[0].mean_ray = Eigen::Vector3d::UnitZ();
    label_sightings[0].keyframes = 10;
  }
  // The photo 8 m behind the wall looks back along -z: through the hole it sees the far wall.
  Eigen::Isometry3d behind = Eigen::Isometry3d::Identity();
  behind.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  behind.translation() = Eigen::Vector3d(0.3, 0.0, 11.0);
  VisibilityOptions options;
  std::vector<ApplianceInView> result =
      AppliancesInView(labels, &cloud, intrinsics_, behind, options, &sightings);
  ASSERT_EQ(result.size(), 2u);
  EXPECT_EQ(result[0].name, "lamp");
  EXPECT_FALSE(result[0].occluded) << "its own surface is drawn where it stands";
  EXPECT_EQ(result[1].name, "tv");
  EXPECT_TRUE(result[1].occluded) << "the z-buffer reaches past it, to the next room";
  options.behind_needs_own_surface = false;
  result = AppliancesInView(labels, &cloud, intrinsics_, behind, options, &sightings);
  ASSERT_EQ(result.size(), 2u);
  EXPECT_FALSE(result[1].occluded);

  // With nothing drawn beyond the hole (no next room in the cloud) nothing is known: visible, as
  // a ceiling light is from across the room when the walk never looked at the ceiling round it.
  OcclusionCloudBuilder open_builder(0.05);
  for (double x = -3.0; x <= 3.0; x += 0.02) {
    for (double y = -2.5; y <= 2.5; y += 0.02) {
      if (std::abs(x) < 0.5 && std::abs(y) < 0.5) continue;
      open_builder.AddPoint({x, y, 3.0});
    }
  }
  const OcclusionCloud open_cloud = open_builder.Build();
  options.behind_needs_own_surface = true;
  result = AppliancesInView(labels, &open_cloud, intrinsics_, behind, options, &sightings);
  ASSERT_EQ(result.size(), 2u);
  EXPECT_EQ(result[1].name, "tv");
  EXPECT_FALSE(result[1].occluded);
}

TEST_F(VisibilityTest, AKeyframesDepthlessScreenHidesWhatLiesBehindItUnlessAViewSawThrough) {
  // A keyframe 2 m before a wall (z = 3), facing it; a 0.9 x 0.6 m screen in the middle of its
  // view returns no depth. A label 3 m behind the wall, seen by a photo through the screen.
  const Intrinsics keyframe = Intrinsics::FromFieldOfView(640, 480, 1.0, 0.0);
  Eigen::Isometry3d world_from_keyframe = Eigen::Isometry3d::Identity();
  world_from_keyframe.translation() = Eigen::Vector3d(0.0, 0.0, 1.0);
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(2000));
  const Eigen::Vector2d corner_a = keyframe.Project({-0.45, -0.3, 2.0});
  const Eigen::Vector2d corner_b = keyframe.Project({0.45, 0.3, 2.0});
  depth(cv::Rect(cv::Point(static_cast<int>(corner_a.x()), static_cast<int>(corner_a.y())),
                 cv::Point(static_cast<int>(corner_b.x()), static_cast<int>(corner_b.y()))))
      .setTo(0);
  const std::vector<store::LabelRecord> labels = {Label("next_room", {{0.1, 0.0, 6.0}})};
  const VisibilityOptions options;
  auto occluded = [&](int max_hole_fill_samples, const std::vector<SightingView>& views) {
    OcclusionCloudBuilder builder(0.05);
    builder.AddDepth(depth, keyframe, world_from_keyframe, 4, 0.3, 5.0, max_hole_fill_samples);
    const OcclusionCloud cloud = builder.Build(views);
    const std::vector<ApplianceInView> result =
        AppliancesInView(labels, &cloud, intrinsics_, Eigen::Isometry3d::Identity(), options);
    EXPECT_EQ(result.size(), 1u);
    return !result.empty() && result[0].occluded;
  };
  // The screen spans about 65 x 44 of the keyframe's 160 x 120 samples: its middle is 22-33
  // samples from its edges.
  EXPECT_FALSE(occluded(0, {})) << "the hole stays open";
  EXPECT_FALSE(occluded(20, {})) << "out of reach of its middle";
  EXPECT_TRUE(occluded(40, {}));
  // Another keyframe, 1.5 m to the side, saw the room beyond through the same opening (a doorway
  // onto a room beyond the first keyframe's range): nothing stands there.
  Eigen::Isometry3d world_from_other = Eigen::Isometry3d::Identity();
  world_from_other.translation() = Eigen::Vector3d(0.3, 0.0, 1.5);
  const cv::Mat far(60, 80, CV_16UC1, cv::Scalar(4500));
  EXPECT_FALSE(
      occluded(40, {MakeSightingView(far, keyframe.Scaled(80, 60), world_from_other, 80, 60)}));
  // One that saw a surface just behind the opening's plane does not clear it.
  const cv::Mat near(60, 80, CV_16UC1, cv::Scalar(1550));
  EXPECT_TRUE(
      occluded(40, {MakeSightingView(near, keyframe.Scaled(80, 60), world_from_other, 80, 60)}));
}

TEST(FillEnclosedHolesTest, EnclosedHolesTakeTheFarthestEdgeOpenOrWideOnesStayEmpty) {
  const float inf = std::numeric_limits<float>::infinity();
  cv::Mat depth(10, 12, CV_32FC1, cv::Scalar(2.0f));
  // An enclosed 2 x 2 hole; its right neighbour farther (3 m).
  depth(cv::Rect(4, 4, 2, 2)).setTo(inf);
  depth.at<float>(4, 6) = 3.0f;
  // A hole touching the image's top edge: not enclosed from above.
  depth(cv::Rect(9, 0, 2, 3)).setTo(inf);
  cv::Mat filled = depth.clone();
  FillEnclosedHoles(2, &filled);
  EXPECT_FLOAT_EQ(filled.at<float>(4, 4), 3.0f);  // its row reaches the 3 m pixel
  EXPECT_FLOAT_EQ(filled.at<float>(5, 5), 2.0f);
  EXPECT_TRUE(std::isinf(filled.at<float>(0, 9)));
  EXPECT_TRUE(std::isinf(filled.at<float>(2, 10)));
  EXPECT_FLOAT_EQ(filled.at<float>(7, 7), 2.0f);  // drawn pixels unchanged
  // Out of reach: the hole's middle pixels are 2 away from an edge on one side.
  cv::Mat narrow = depth.clone();
  narrow(cv::Rect(2, 2, 5, 5)).setTo(inf);
  FillEnclosedHoles(2, &narrow);
  EXPECT_TRUE(std::isinf(narrow.at<float>(4, 4))) << "3 pixels from every edge";
  cv::Mat untouched = depth.clone();
  FillEnclosedHoles(0, &untouched);
  EXPECT_TRUE(std::isinf(untouched.at<float>(4, 4)));
}

TEST(ClearSightingTest, DepthReachingThePointOrMissingWithinTheSensorsRange) {
  const double margin_m = 0.10;
  const double range_m = 4.5;
  EXPECT_TRUE(ClearSighting(3000, 2.0, margin_m, range_m));   // the surface lies beyond it
  EXPECT_TRUE(ClearSighting(2000, 2.05, margin_m, range_m));  // on it, within the margin
  EXPECT_FALSE(ClearSighting(2000, 2.2, margin_m, range_m));  // something 0.2 m in front
  EXPECT_TRUE(ClearSighting(0, 4.5, margin_m, range_m));      // no depth: a dark screen
  EXPECT_FALSE(ClearSighting(0, 4.6, margin_m, range_m));     // no depth: out of range
}

TEST(VisibilityOptionsTest, CheckRejectsNonsense) {
  VisibilityOptions options;
  EXPECT_TRUE(options.Check(nullptr));
  options.zbuffer_downscale = 0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_FALSE(error.empty());
  options = VisibilityOptions();
  options.free_standing_behind_margin_m = options.behind_margin_m / 2;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("free_standing_behind_margin_m"), std::string::npos) << error;
  LocatorOptions locator;
  EXPECT_TRUE(locator.Check(nullptr));
  locator.min_inliers = 3;
  EXPECT_FALSE(locator.Check(nullptr));
  locator = LocatorOptions();
  locator.match_node_level = -1;
  EXPECT_FALSE(locator.Check(&error));
  EXPECT_NE(error.find("match_node_level"), std::string::npos) << error;
  locator = LocatorOptions();
  locator.slide.min_sd_m = 0.0;  // off
  EXPECT_TRUE(locator.Check(&error)) << error;
  locator.slide.max_sd_m = 0.0;
  EXPECT_FALSE(locator.Check(&error));
  EXPECT_NE(error.find("slide"), std::string::npos) << error;
  locator = LocatorOptions();
  locator.slide.steps = 0;
  EXPECT_FALSE(locator.Check(&error));
}

}  // namespace
}  // namespace sightmap::identify
