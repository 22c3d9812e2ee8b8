#include "identify/identify_eval.h"

#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/rotation.h"

namespace sightmap::identify {
namespace {

using T = TruthType;

QueryTruth Truth(std::map<std::string, TruthType> appliances) {
  QueryTruth truth;
  truth.appliances = std::move(appliances);
  return truth;
}

PhotoAnswer Answer(bool matched, std::vector<std::string> identified, double total_ms,
                   std::vector<std::string> occluded = {}) {
  PhotoAnswer answer;
  answer.matched = matched;
  if (!matched) answer.reason = "too few inliers";
  answer.identified = std::move(identified);
  answer.reported_occluded = std::move(occluded);
  answer.timings.total_ms = total_ms;
  answer.timings.features_ms = total_ms / 2;
  return answer;
}

// Six photos whose figures are computed by hand in the comments.
struct HandMade {
  std::vector<QueryTruth> truths;
  std::vector<PhotoAnswer> answers;
  HandMade() {
    // A: recall 1/2 (tv missed), precision 2/3 (lamp, partial fan right; occluded door wrong).
    truths.push_back(Truth({{"lamp", T::kVisible},
                            {"tv", T::kVisible},
                            {"fan", T::kPartiallyVisible},
                            {"door", T::kOccluded},
                            {"heater", T::kNotVisible}}));
    answers.push_back(Answer(true, {"lamp", "fan", "door"}, 10));
    // B: recall 1, precision 1; the occluded fan is reported as occluded, which is right.
    truths.push_back(Truth({{"lamp", T::kVisible}, {"tv", T::kNotVisible}, {"fan", T::kOccluded}}));
    answers.push_back(Answer(true, {"lamp"}, 20, {"fan"}));
    // C: nothing visible, nothing identified: recall and precision undefined.
    truths.push_back(Truth({{"lamp", T::kNotVisible}, {"tv", T::kNotVisible}}));
    answers.push_back(Answer(true, {}, 30));
    // D: recall 1/1 (the partial lamp is optional), precision 2/3 (ghost is unknown).
    truths.push_back(Truth({{"lamp", T::kPartiallyVisible}, {"tv", T::kVisible}}));
    answers.push_back(Answer(true, {"lamp", "tv", "ghost", "tv"}, 40));
    // E: recall 4/5, precision 4/5: exactly at the 0.8 threshold.
    truths.push_back(Truth({{"a1", T::kVisible},
                            {"a2", T::kVisible},
                            {"a3", T::kVisible},
                            {"a4", T::kVisible},
                            {"a5", T::kVisible},
                            {"a6", T::kNotVisible}}));
    answers.push_back(Answer(true, {"a1", "a2", "a3", "a4", "a6"}, 50));
    // F: not matched; its instances are not in the table.
    truths.push_back(Truth({{"lamp", T::kVisible}}));
    answers.push_back(Answer(false, {}, 60));
  }
};

TEST(IdentifyEval, HandComputedFigures) {
  const HandMade data;
  const IdentifyEvaluation e = EvaluateIdentification(data.truths, data.answers);
  EXPECT_EQ(e.photos, 6);
  EXPECT_EQ(e.matched_photos, 5);
  EXPECT_DOUBLE_EQ(e.matched_ratio, 5.0 / 6.0);

  // Table: [type][identified].
  EXPECT_EQ(e.categories[static_cast<int>(T::kVisible)][1], 7);  // A1 B1 D1 E4
  EXPECT_EQ(e.categories[static_cast<int>(T::kVisible)][0], 2);  // A tv, E a5
  EXPECT_EQ(e.categories[static_cast<int>(T::kPartiallyVisible)][1], 2);
  EXPECT_EQ(e.categories[static_cast<int>(T::kPartiallyVisible)][0], 0);
  EXPECT_EQ(e.categories[static_cast<int>(T::kOccluded)][1], 1);
  EXPECT_EQ(e.categories[static_cast<int>(T::kOccluded)][0], 1);
  EXPECT_EQ(e.categories[static_cast<int>(T::kNotVisible)][1], 1);  // E a6
  EXPECT_EQ(e.categories[static_cast<int>(T::kNotVisible)][0], 4);  // A heater, B tv, C lamp+tv
  EXPECT_EQ(e.unknown_identified, 1);
  EXPECT_EQ(e.not_visible_identified, 1);

  ASSERT_EQ(e.recall.size(), 5u);
  EXPECT_DOUBLE_EQ(*e.recall[0], 0.5);
  EXPECT_DOUBLE_EQ(*e.recall[1], 1.0);
  EXPECT_FALSE(e.recall[2].has_value());
  EXPECT_DOUBLE_EQ(*e.recall[3], 1.0);
  EXPECT_DOUBLE_EQ(*e.recall[4], 0.8);
  EXPECT_DOUBLE_EQ(*e.precision[0], 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(*e.precision[1], 1.0);
  EXPECT_FALSE(e.precision[2].has_value());
  EXPECT_DOUBLE_EQ(*e.precision[3], 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(*e.precision[4], 0.8);

  EXPECT_EQ(e.recall_defined_photos, 4);
  EXPECT_EQ(e.recall_good_photos, 3);  // B, D, E
  EXPECT_DOUBLE_EQ(e.recall_ge_0_8_ratio, 0.75);
  EXPECT_EQ(e.precision_defined_photos, 4);
  EXPECT_EQ(e.precision_good_photos, 2);  // B, E
  EXPECT_DOUBLE_EQ(e.precision_ge_0_8_ratio, 0.5);

  // 10 bins over [0, 1) and one for 1.0.
  EXPECT_EQ(e.recall_histogram, (std::vector<int>{0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 2}));
  EXPECT_EQ(e.precision_histogram, (std::vector<int>{0, 0, 0, 0, 0, 0, 2, 0, 1, 0, 1}));

  EXPECT_EQ(e.occluded_instances, 2);
  EXPECT_EQ(e.occluded_identified, 1);
  EXPECT_DOUBLE_EQ(e.occluded_false_positive_ratio, 0.5);

  // Timings over all six photos: 10..60 ms.
  EXPECT_DOUBLE_EQ(e.stages.at("total").median_ms, 35.0);
  EXPECT_DOUBLE_EQ(e.stages.at("total").p95_ms, 57.5);  // 50 + 0.75 * 10
  EXPECT_DOUBLE_EQ(e.stages.at("total").mean_ms, 35.0);
  EXPECT_DOUBLE_EQ(e.stages.at("total").max_ms, 60.0);
  EXPECT_DOUBLE_EQ(e.stages.at("features").median_ms, 17.5);
  EXPECT_EQ(e.unmatched_reasons.at("too few inliers"), 1);
}

TEST(IdentifyEval, JsonHasTheStableKeys) {
  const HandMade data;
  const nlohmann::json j = ToJson(EvaluateIdentification(data.truths, data.answers));
  for (const char* key :
       {"photos", "matched_ratio", "recall_ge_0_8_ratio", "precision_ge_0_8_ratio",
        "occluded_false_positive_ratio", "locate_median_ms", "locate_p95_ms", "categories",
        "stages_ms", "features_median_ms", "pnp_p95_ms", "recall_undefined_photos"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["photos"], 6);
  EXPECT_DOUBLE_EQ(j["locate_median_ms"].get<double>(), 35.0);
  EXPECT_EQ(j["categories"]["visible"]["identified"], 7);
  EXPECT_EQ(j["categories"]["occluded"]["not_identified"], 1);
  EXPECT_EQ(j["recall_undefined_photos"], 1);
}

TEST(IdentifyEval, NoPhotosGivesZerosNotNaN) {
  const IdentifyEvaluation e = EvaluateIdentification({}, {});
  EXPECT_EQ(e.photos, 0);
  EXPECT_EQ(e.matched_ratio, 0.0);
  EXPECT_EQ(e.recall_ge_0_8_ratio, 0.0);
  EXPECT_EQ(e.stages.count("total"), 0u);
  EXPECT_EQ(ToJson(e)["locate_p95_ms"], 0.0);
  EXPECT_FALSE(DrawIdentifyPlot(e).empty());
}

TEST(IdentifyEval, MismatchedInputsThrow) {
  EXPECT_THROW(EvaluateIdentification({QueryTruth()}, {}), Error);
  IdentifyEvalOptions bad;
  bad.good_share = 1.5;
  EXPECT_THROW(EvaluateIdentification({}, {}, bad), InvalidArgument);
}

TEST(IdentifyEval, PercentileInterpolates) {
  EXPECT_DOUBLE_EQ(Percentile({3, 1, 2}, 0.5), 2.0);
  EXPECT_DOUBLE_EQ(Percentile({1, 2}, 0.5), 1.5);
  EXPECT_DOUBLE_EQ(Percentile({7}, 0.95), 7.0);
  EXPECT_DOUBLE_EQ(Percentile({}, 0.5), 0.0);
}

TEST(IdentifyEval, ToPhotoAnswerSplitsOccluded) {
  LocateResult result;
  result.matched = true;
  result.appliances.push_back({"lamp", "lamp", Eigen::Vector2d(1, 2), 1.0, false});
  result.appliances.push_back({"tv", "tv", Eigen::Vector2d(3, 4), 2.0, true});
  result.timings.pnp_ms = 5;
  const PhotoAnswer answer = ToPhotoAnswer(result);
  EXPECT_EQ(answer.identified, std::vector<std::string>{"lamp"});
  EXPECT_EQ(answer.reported_occluded, std::vector<std::string>{"tv"});
  EXPECT_EQ(answer.timings.pnp_ms, 5);
  EXPECT_FALSE(answer.refused_world_from_cam.has_value());
  result.matched = false;  // an unmatched answer identifies nothing, and keeps the refused pose
  result.refused_world_from_cam = Eigen::Isometry3d(Eigen::Translation3d(0, 1, 0));
  result.refused_inliers = 40;
  const PhotoAnswer refused = ToPhotoAnswer(result);
  EXPECT_TRUE(refused.identified.empty());
  ASSERT_TRUE(refused.refused_world_from_cam.has_value());
  EXPECT_EQ(refused.refused_world_from_cam->translation().y(), 1.0);
  EXPECT_EQ(refused.refused_inliers, 40);
}

TEST(IdentifyEval, ReadsQueriesFromTheDatasetOrQueriesFolder) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("identify_eval_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "queries");
  std::ofstream(dir / "queries" / "0000.jpg") << "x";
  std::ofstream(dir / "queries" / "queries.json") << R"({"queries": [{
      "image": "queries/0000.jpg",
      "intrinsics": {"width": 1280, "height": 960, "fx": 1000, "fy": 1001, "cx": 640, "cy": 480},
      "types": {"lamp": "visible", "tv": "partially_visible", "fan": "occluded",
                "door": "not_visible"},
      "target": "lamp",
      "world_from_cam": {"position": [1, 2, 3], "quaternion_xyzw": [0, 0, 0.7071068, 0.7071068]}}]})";
  for (const fs::path& path : {dir, dir / "queries", dir / "queries" / "queries.json"}) {
    const std::vector<QueryTruth> truths = ReadQueryTruths(path.string());
    ASSERT_EQ(truths.size(), 1u) << path;
    EXPECT_TRUE(fs::equivalent(truths[0].image_path, dir / "queries" / "0000.jpg"));
    ASSERT_TRUE(truths[0].intrinsics.has_value());
    EXPECT_EQ(truths[0].intrinsics->width, 1280);
    EXPECT_EQ(truths[0].intrinsics->fy, 1001);
    EXPECT_EQ(truths[0].appliances.at("lamp"), T::kVisible);
    EXPECT_EQ(truths[0].appliances.at("tv"), T::kPartiallyVisible);
    EXPECT_EQ(truths[0].appliances.at("fan"), T::kOccluded);
    EXPECT_EQ(truths[0].appliances.at("door"), T::kNotVisible);
    EXPECT_EQ(truths[0].target, "lamp");
    ASSERT_TRUE(truths[0].world_from_cam.has_value());
    EXPECT_TRUE(truths[0].world_from_cam->translation().isApprox(Eigen::Vector3d(1, 2, 3)));
    // 90 deg about z: the camera's x axis along world y.
    EXPECT_TRUE(truths[0].world_from_cam->linear().col(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-6));
    EXPECT_FALSE(truths[0].covered.has_value());
  }
  try {
    ReadQueryTruths((dir / "nowhere").string());
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no queries.json"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "queries" / "queries.json") << R"({"queries": [{"image": "a.jpg",
      "types": {"lamp": "sort_of"}}]})";
  EXPECT_THROW(ReadQueryTruths(dir.string()), Error);
  fs::remove_all(dir);
}

TEST(IdentifyEval, WrongPosesAreCountedAndPhotosSplitByCoverage) {
  // Three matched photos: 0.1 m / 1 deg off, 0.6 m off, 12 deg off; one unmatched; one matched
  // without a true pose.
  std::vector<QueryTruth> truths(5, Truth({{"lamp", T::kVisible}}));
  std::vector<PhotoAnswer> answers;
  const Eigen::Isometry3d truth_pose(Eigen::Translation3d(1, 2, 1.5));
  auto moved = [&](const Eigen::Vector3d& shift, double turn_deg) {
    Eigen::Isometry3d pose = truth_pose;
    pose.translation() += shift;
    pose.linear() = Eigen::AngleAxisd(DegToRad(turn_deg), Eigen::Vector3d(0, 0.6, 0.8)).matrix();
    return pose;
  };
  for (size_t i = 0; i < 4; ++i) truths[i].world_from_cam = truth_pose;
  for (const auto& [shift, turn] : {std::make_pair(Eigen::Vector3d(0.1, 0, 0), 1.0),
                                    std::make_pair(Eigen::Vector3d(0, 0.6, 0), 0.0),
                                    std::make_pair(Eigen::Vector3d(0, 0, 0), 12.0)}) {
    answers.push_back(Answer(true, {"lamp"}, 10));
    answers.back().world_from_cam = moved(shift, turn);
  }
  answers.push_back(Answer(false, {}, 10));
  answers.push_back(Answer(true, {"lamp"}, 10));
  answers.back().world_from_cam = truth_pose;

  const PoseError error = ComparePoses(truth_pose, moved({0.1, 0, 0}, 1.0));
  EXPECT_NEAR(error.position_m, 0.1, 1e-12);
  EXPECT_NEAR(error.rotation_deg, 1.0, 1e-9);

  const IdentifyEvaluation e = EvaluateIdentification(truths, answers);
  EXPECT_EQ(e.matched_photos, 4);
  EXPECT_EQ(e.posed_photos, 3);
  EXPECT_EQ(e.wrong_poses, 2);
  EXPECT_DOUBLE_EQ(e.wrong_pose_ratio, 2.0 / 4.0);
  EXPECT_NEAR(e.median_position_error_m, 0.1, 1e-12);   // of 0.1, 0.6, 0
  EXPECT_NEAR(e.median_rotation_error_deg, 1.0, 1e-9);  // of 1, 0, 12
  const nlohmann::json json = ToJson(e);
  for (const char* key : {"posed_photos", "wrong_poses", "wrong_pose_ratio",
                          "median_position_error_m", "median_rotation_error_deg"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }

  // Photos 0 and 3 covered, 1 not, the rest unknown.
  truths[0].covered = true;
  truths[3].covered = true;
  truths[1].covered = false;
  std::vector<QueryTruth> selected_truths;
  std::vector<PhotoAnswer> selected_answers;
  SelectCovered(truths, answers, true, &selected_truths, &selected_answers);
  ASSERT_EQ(selected_truths.size(), 2u);
  EXPECT_TRUE(selected_answers[0].matched);
  EXPECT_FALSE(selected_answers[1].matched);
  const IdentifyEvaluation covered = EvaluateIdentification(selected_truths, selected_answers);
  EXPECT_EQ(covered.matched_photos, 1);
  EXPECT_EQ(covered.wrong_poses, 0);
  SelectCovered(truths, answers, false, &selected_truths, &selected_answers);
  ASSERT_EQ(selected_truths.size(), 1u);
  EXPECT_EQ(EvaluateIdentification(selected_truths, selected_answers).wrong_poses, 1);
}

TEST(IdentifyEval, RetrievalRecallCountsTheFirstKeyframeThatSawTheView) {
  // Keyframes 7 and 9 saw photo 0's view; 4 saw photo 1's; nothing saw photo 2's (not counted).
  std::vector<QueryTruth> truths(3, Truth({{"lamp", T::kVisible}}));
  truths[0].seeing_keyframes = {9, 7};
  truths[1].seeing_keyframes = {4};
  std::vector<PhotoAnswer> answers(3, Answer(false, {}, 10));
  answers[0].retrieved = {3, -1, 5, 9, 7};  // 9 at rank 4; a synthetic view (-1) holds a rank
  answers[1].retrieved = {3, 5};            // 4 never retrieved
  answers[2].retrieved = {4};
  EXPECT_EQ(RetrievalRank(answers[0].retrieved, truths[0].seeing_keyframes), 4);
  EXPECT_FALSE(RetrievalRank(answers[1].retrieved, truths[1].seeing_keyframes));
  EXPECT_FALSE(RetrievalRank({-1, 2}, {}));

  IdentifyEvalOptions options;
  options.retrieval_ranks = {1, 4, 60};
  const IdentifyEvaluation e = EvaluateIdentification(truths, answers, options);
  EXPECT_EQ(e.retrieval_photos, 2);
  EXPECT_EQ(e.retrieval_found, (std::vector<int>{0, 1, 1}));
  const nlohmann::json json = ToJson(e);
  EXPECT_EQ(json.at("retrieval_photos"), 2);
  EXPECT_DOUBLE_EQ(json.at("retrieval_recall").at("4").get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(json.at("retrieval_recall").at("1").get<double>(), 0.0);
  const std::vector<nlohmann::json> rows = PhotoRows(truths, answers);
  EXPECT_EQ(rows[0].at("retrieval_rank"), 4);
  EXPECT_EQ(rows[0].at("seeing_keyframes"), 2);
  EXPECT_TRUE(rows[1].at("retrieval_rank").is_null());
  EXPECT_TRUE(rows[2].at("retrieval_rank").is_null());

  options.retrieval_ranks = {0};
  EXPECT_THROW(EvaluateIdentification(truths, answers, options), InvalidArgument);
}

TEST(IdentifyEval, AmbiguousAnswersCountWhetherOneOfTheirPlacesIsRight) {
  const Eigen::Isometry3d truth_pose(Eigen::Translation3d(1, 2, 1.5));
  std::vector<QueryTruth> truths(4, Truth({{"lamp", T::kVisible}}));
  for (size_t i = 0; i < 3; ++i) truths[i].world_from_cam = truth_pose;
  const auto at = [&](double x) {
    Eigen::Isometry3d pose = truth_pose;
    pose.translation().x() += x;
    return pose;
  };
  std::vector<PhotoAnswer> answers(4, Answer(false, {}, 10));
  answers[0].possible_places = {at(2.2), at(0.1)};   // the right desk second
  answers[1].possible_places = {at(6.0), at(10.0)};  // two wrong places
  // answers[2]: unmatched for another reason; answers[3]: ambiguous without a true pose.
  answers[3].possible_places = {at(0.0), at(3.0)};
  const IdentifyEvaluation e = EvaluateIdentification(truths, answers);
  EXPECT_EQ(e.ambiguous_photos, 3);
  EXPECT_EQ(e.ambiguous_right_place_photos, 1);
  const nlohmann::json json = ToJson(e);
  EXPECT_EQ(json["ambiguous_photos"], 3);
  EXPECT_EQ(json["ambiguous_right_place_photos"], 1);
  const std::vector<nlohmann::json> rows = PhotoRows(truths, answers);
  ASSERT_EQ(rows[0]["possible_place_position_errors_m"].size(), 2u);
  EXPECT_NEAR(rows[0]["possible_place_position_errors_m"][1].get<double>(), 0.1, 1e-9);
  EXPECT_TRUE(rows[2]["possible_place_position_errors_m"].empty());
  EXPECT_TRUE(rows[3]["possible_place_position_errors_m"].empty());  // no true pose
}

TEST(IdentifyEval, PhotoRowsNameEachPhotosAnswerAndError) {
  std::vector<QueryTruth> truths(3, Truth({{"lamp", T::kVisible}}));
  const Eigen::Isometry3d truth_pose(Eigen::Translation3d(1, 2, 1.5));
  for (QueryTruth& truth : truths) {
    truth.world_from_cam = truth_pose;
    truth.target = "lamp";
  }
  truths[0].image_path = "q/0.jpg";
  truths[0].covered = true;
  truths[0].view_angle_deg = 12.5;
  truths[1].covered = false;
  std::vector<PhotoAnswer> answers;
  answers.push_back(Answer(true, {"lamp"}, 10));  // 0.7 m off: wrong
  answers[0].world_from_cam = truth_pose * Eigen::Translation3d(0.7, 0, 0);
  answers[0].inliers = 123;
  answers[0].keyframe = 42;
  answers[0].inlier_cells = 9;
  answers[0].runner_up_inliers = 31;
  answers[0].photo_detail_cells = 12;
  answers[0].view_agreement = 0.62;
  answers.push_back(Answer(false, {}, 10));
  answers[1].photo_detail_cells = 2;
  answers[1].inlier_cells = 5;  // not matched: not reported
  answers[1].second_look = true;
  answers[1].timings.matching_ms = 40.0;
  answers[1].timings.second_look_ms = 25.0;
  answers[1].refused_world_from_cam = truth_pose * Eigen::Translation3d(0, 0, 0.3);
  answers[1].refused_inliers = 64;
  answers.push_back(Answer(true, {}, 10));  // right
  answers[2].world_from_cam = truth_pose * Eigen::Translation3d(0, 0.05, 0);

  const std::vector<nlohmann::json> rows = PhotoRows(truths, answers);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0]["index"], 0);
  EXPECT_EQ(rows[0]["image"], "q/0.jpg");
  EXPECT_EQ(rows[0]["target"], "lamp");
  EXPECT_EQ(rows[0]["covered"], true);
  EXPECT_DOUBLE_EQ(rows[0]["view_angle_deg"].get<double>(), 12.5);
  EXPECT_TRUE(rows[1]["view_angle_deg"].is_null());
  EXPECT_EQ(rows[0]["matched"], true);
  EXPECT_TRUE(rows[0]["reason"].is_null());
  EXPECT_EQ(rows[0]["inliers"], 123);
  EXPECT_EQ(rows[0]["keyframe"], 42);
  EXPECT_NEAR(rows[0]["position_error_m"].get<double>(), 0.7, 1e-12);
  EXPECT_NEAR(rows[0]["rotation_error_deg"].get<double>(), 0.0, 1e-9);
  EXPECT_EQ(rows[0]["wrong_pose"], true);
  EXPECT_NEAR(rows[0]["world_from_cam"]["position"][0].get<double>(), 1.7, 1e-12);
  EXPECT_NEAR(rows[0]["world_from_cam"]["quaternion_xyzw"][3].get<double>(), 1.0, 1e-12);
  EXPECT_TRUE(rows[1]["world_from_cam"].is_null());
  EXPECT_EQ(rows[0]["identified"], nlohmann::json::array({"lamp"}));
  EXPECT_EQ(rows[0]["inlier_cells"], 9);
  EXPECT_EQ(rows[0]["runner_up_inliers"], 31);
  EXPECT_EQ(rows[0]["photo_detail_cells"], 12);
  EXPECT_DOUBLE_EQ(rows[0]["view_agreement"].get<double>(), 0.62);
  EXPECT_TRUE(rows[1]["view_agreement"].is_null());
  EXPECT_TRUE(rows[1]["inlier_cells"].is_null());
  EXPECT_EQ(rows[1]["photo_detail_cells"], 2);
  EXPECT_EQ(rows[0]["second_look"], false);
  EXPECT_EQ(rows[1]["second_look"], true);
  EXPECT_DOUBLE_EQ(rows[1]["timings_ms"]["matching"].get<double>(), 40.0);
  EXPECT_DOUBLE_EQ(rows[1]["timings_ms"]["second_look"].get<double>(), 25.0);
  EXPECT_DOUBLE_EQ(rows[0]["timings_ms"]["second_look"].get<double>(), 0.0);
  EXPECT_EQ(EvaluateIdentification(truths, answers).second_look_photos, 1);

  EXPECT_EQ(rows[1]["covered"], false);
  EXPECT_EQ(rows[1]["matched"], false);
  EXPECT_EQ(rows[1]["reason"], "too few inliers");
  EXPECT_TRUE(rows[1]["inliers"].is_null());
  EXPECT_TRUE(rows[1]["keyframe"].is_null());
  EXPECT_TRUE(rows[1]["wrong_pose"].is_null());
  EXPECT_EQ(rows[1]["refused_inliers"], 64);
  EXPECT_NEAR(rows[1]["refused_position_error_m"].get<double>(), 0.3, 1e-12);
  EXPECT_NEAR(rows[1]["refused_rotation_error_deg"].get<double>(), 0.0, 1e-9);
  EXPECT_TRUE(rows[0]["refused_inliers"].is_null());  // matched
  EXPECT_TRUE(rows[2]["refused_position_error_m"].is_null());

  EXPECT_TRUE(rows[2]["covered"].is_null());
  EXPECT_EQ(rows[2]["wrong_pose"], false);
  EXPECT_TRUE(rows[2]["keyframe"].is_null());
  // The rows count wrong poses as the evaluation does.
  EXPECT_EQ(EvaluateIdentification(truths, answers).wrong_poses, 1);
  EXPECT_ANY_THROW(PhotoRows(truths, {}));
}

TEST(IdentifyEval, PlotShowsRightAndWrongColours) {
  const HandMade data;
  const cv::Mat plot =
      DrawIdentifyPlot(EvaluateIdentification(data.truths, data.answers), 1200, 560);
  ASSERT_EQ(plot.cols, 1200);
  ASSERT_EQ(plot.rows, 560);
  int green = 0;
  int red = 0;
  for (int y = 0; y < plot.rows; ++y) {
    for (int x = 0; x < plot.cols; ++x) {
      const cv::Vec3b p = plot.at<cv::Vec3b>(y, x);
      green += p == cv::Vec3b(80, 170, 60) ? 1 : 0;
      red += p == cv::Vec3b(60, 60, 210) ? 1 : 0;
    }
  }
  EXPECT_GT(green, 1000);
  EXPECT_GT(red, 1000);
  EXPECT_THROW(DrawIdentifyPlot(EvaluateIdentification({}, {}), 100, 100), Error);
}

}  // namespace
}  // namespace sightmap::identify
