#include "slam/trajectory_eval.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "core/check.h"

namespace sightmap::slam {
namespace {

// A 4 m x 3 m rectangle walked at 0.5 m/s, one pose per second, looking along the path.
std::vector<StampedPose> Rectangle() {
  std::vector<StampedPose> poses;
  const Eigen::Vector3d corners[] = {{0, 0, 0}, {4, 0, 0}, {4, 3, 0}, {0, 3, 0}, {0, 0, 0}};
  TimestampNs t = 0;
  for (int side = 0; side < 4; ++side) {
    const Eigen::Vector3d step =
        (corners[side + 1] - corners[side]) / ((corners[side + 1] - corners[side]).norm() / 0.5);
    const int steps =
        static_cast<int>(std::lround((corners[side + 1] - corners[side]).norm() / 0.5));
    for (int i = 0; i < steps; ++i) {
      StampedPose pose;
      pose.timestamp_ns = t;
      pose.world_from_cam.translation() = corners[side] + i * step;
      pose.world_from_cam.linear() =
          Eigen::AngleAxisd(side * M_PI / 2, Eigen::Vector3d::UnitZ()).matrix();
      poses.push_back(pose);
      t += 1'000'000'000;
    }
  }
  return poses;
}

TEST(TrajectoryEval, RigidlyMovedCopyHasNoError) {
  const std::vector<StampedPose> gt = Rectangle();
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  offset.translation() = Eigen::Vector3d(10, -3, 2);
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) pose.world_from_cam = offset * pose.world_from_cam;
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_EQ(error.matched_poses, static_cast<int>(gt.size()));
  EXPECT_LT(error.ate_rmse_m, 1e-9);
  EXPECT_LT(error.rpe_trans_per_m, 1e-9);
  EXPECT_LT(error.rpe_rot_deg_per_m, 1e-6);
  EXPECT_TRUE((error.gt_from_est * offset).matrix().isIdentity(1e-9));
}

TEST(TrajectoryEval, AUniformlySmallMapShowsItsScale) {
  const std::vector<StampedPose> gt = Rectangle();
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).matrix();
  offset.translation() = Eigen::Vector3d(2, 1, 0);
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) {
    pose.world_from_cam.translation() *= 0.99;  // the map 1% small
    pose.world_from_cam = offset * pose.world_from_cam;
  }
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_GT(error.ate_rmse_m, 0.005);
  EXPECT_NEAR(error.sim3_scale, 1.0 / 0.99, 1e-9);
  EXPECT_LT(error.sim3_ate_rmse_m, 1e-9);
  EXPECT_EQ(error.timestamps_ns.size(), gt.size());

  const TrajectoryError exact = EvaluateTrajectory(gt, gt);
  EXPECT_NEAR(exact.sim3_scale, 1.0, 1e-12);
}

TEST(TrajectoryEval, WorstStretchesAndConcentrationFindWhereTheErrorIs) {
  const std::vector<StampedPose> gt = Rectangle();  // 28 poses, t = 0-27 s
  std::vector<StampedPose> est = gt;
  est[6].world_from_cam.translation().z() += 0.3;
  est[7].world_from_cam.translation().z() += 0.3;
  const TrajectoryError error = EvaluateTrajectory(gt, est);

  const std::vector<ErrorStretch> worst = WorstStretches(error, 5.0, 2);
  ASSERT_EQ(worst.size(), 2u);
  EXPECT_DOUBLE_EQ(worst[0].start_s, 5.0);
  EXPECT_DOUBLE_EQ(worst[0].end_s, 10.0);
  EXPECT_EQ(worst[0].poses, 5);
  EXPECT_GT(worst[0].max_m, 0.2);
  EXPECT_GT(worst[0].mean_m, 2.0 * worst[1].mean_m);
  EXPECT_EQ(WorstStretches(error, 5.0, 10).size(), 6u);  // 0-5, ..., 25-30 s

  const ErrorConcentration concentration = ConcentrationOfError(error, 2.0 / 28.0);
  EXPECT_EQ(concentration.worst_poses, 2);
  EXPECT_GT(concentration.worst_share, 0.7);  // 2 of 28 poses; the alignment tilts a little
  EXPECT_LT(concentration.rest_rmse_m, 0.06);
  EXPECT_LT(concentration.rest_rmse_m, error.ate_rmse_m / 2.0);
  EXPECT_THROW(ConcentrationOfError(error, 1.5), Error);
  EXPECT_THROW(WorstStretches(error, 0.0, 1), Error);
  // A window far shorter than the walk: one stretch per pose, the raised ones first.
  const std::vector<ErrorStretch> fine = WorstStretches(error, 1e-6, 100);
  ASSERT_EQ(fine.size(), 28u);
  EXPECT_EQ(fine[0].poses, 1);
  EXPECT_NEAR(std::min(fine[0].start_s, fine[1].start_s), 6.0, 1e-6);
  EXPECT_NEAR(std::max(fine[0].start_s, fine[1].start_s), 7.0, 1e-6);
}

TEST(TrajectoryEval, KnownOffsetsGiveKnownAte) {
  const std::vector<StampedPose> gt = Rectangle();
  // Alternate +-5 cm along z: the alignment cannot remove it, every error is 5 cm.
  std::vector<StampedPose> est = gt;
  for (size_t i = 0; i < est.size(); ++i) {
    est[i].world_from_cam.translation().z() += (i % 2 == 0 ? 0.05 : -0.05);
  }
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_NEAR(error.ate_rmse_m, 0.05, 1e-3);
  EXPECT_NEAR(error.ate_max_m, 0.05, 1e-3);
  EXPECT_NEAR(error.ate_median_m, 0.05, 1e-3);
  // Over 1 m (two steps) both ends carry the same offset: no relative error.
  EXPECT_LT(error.rpe_trans_per_m, 1e-9);
}

TEST(TrajectoryEval, KnownOffsetsGiveKnownRpe) {
  const std::vector<StampedPose> gt = Rectangle();
  // Offsets +5, +5, -5, -5 cm repeating: poses two steps (1 m, 2 s) apart always differ by 10 cm.
  std::vector<StampedPose> est = gt;
  for (size_t i = 0; i < est.size(); ++i) {
    est[i].world_from_cam.translation().z() += (i % 4 < 2 ? 0.05 : -0.05);
  }
  const TrajectoryEvalOptions options;
  const TrajectoryError error = EvaluateTrajectory(gt, est, options);
  EXPECT_NEAR(error.rpe_trans_per_m, 0.1, 1e-9);
  EXPECT_GT(error.rpe_pairs_distance, 20);
}

TEST(TrajectoryEval, DriftShowsInRpePerMetre) {
  const std::vector<StampedPose> gt = Rectangle();
  // A scale drift of 2%: every metre walked is estimated as 1.02 m.
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) pose.world_from_cam.translation() *= 1.02;
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_NEAR(error.rpe_trans_per_m, 0.02, 2e-3);
  EXPECT_GT(error.rpe_pairs_distance, 10);
  EXPECT_NEAR(error.rpe_trans_per_s, 0.02 * 0.5, 2e-3);
}

TEST(TrajectoryEval, MatchesByTimestampAndRefusesDisjointClocks) {
  const std::vector<StampedPose> gt = Rectangle();
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) pose.timestamp_ns += 5'000'000;  // 5 ms late: still matched
  EXPECT_EQ(EvaluateTrajectory(gt, est).matched_poses, static_cast<int>(gt.size()));
  for (StampedPose& pose : est) pose.timestamp_ns += 1'000'000'000'000;
  EXPECT_THROW(EvaluateTrajectory(gt, est), Error);
}

TEST(TrajectoryEval, MedianOfAnEvenCountIsTheMeanOfTheMiddleTwo) {
  // Two concentric squares in the z = 0 plane; the estimate moves the small square's corners by
  // +-1 cm and the big square's by +-3 cm along z, alternating round each square. Those offsets
  // have zero mean and no correlation with x or y, so the alignment is the identity and the errors
  // are exactly 1, 1, 1, 1, 3, 3, 3, 3 cm: median (1 + 3) / 2 = 2 cm, not the upper middle 3 cm.
  std::vector<StampedPose> gt;
  std::vector<StampedPose> est;
  const double corners[4][2] = {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
  for (const double size : {1.0, 2.0}) {
    for (int i = 0; i < 4; ++i) {
      StampedPose pose;
      pose.timestamp_ns = static_cast<TimestampNs>(gt.size()) * 1'000'000'000;
      pose.world_from_cam.translation() =
          Eigen::Vector3d(size * corners[i][0], size * corners[i][1], 0.0);
      gt.push_back(pose);
      pose.world_from_cam.translation().z() = (i % 2 == 0 ? 1 : -1) * (size == 1.0 ? 0.01 : 0.03);
      est.push_back(pose);
    }
  }
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_EQ(error.matched_poses, 8);
  EXPECT_TRUE(error.gt_from_est.matrix().isIdentity(1e-12));
  EXPECT_NEAR(error.ate_median_m, 0.02, 1e-12);
  EXPECT_NEAR(error.ate_mean_m, 0.02, 1e-12);
  EXPECT_NEAR(error.ate_max_m, 0.03, 1e-12);
  EXPECT_NEAR(error.ate_rmse_m, std::sqrt((0.01 * 0.01 + 0.03 * 0.03) / 2), 1e-12);
}

TEST(TrajectoryEval, MatchesOneToOneWhenTheEstimateIsDenser) {
  // An estimate at twice the ground truth's rate, the extra poses 10 ms after each ground-truth
  // time (within the 20 ms tolerance) and 5 mm further on. Before one-to-one matching each
  // ground-truth pose was compared with both estimates, counting their 10 ms of motion as error.
  const std::vector<StampedPose> gt = Rectangle();
  std::vector<StampedPose> est;
  for (const StampedPose& pose : gt) {
    est.push_back(pose);
    StampedPose later = pose;
    later.timestamp_ns += 10'000'000;
    later.world_from_cam.translation() += pose.world_from_cam.linear().col(0) * 0.005;
    est.push_back(later);
  }
  const TrajectoryError error = EvaluateTrajectory(gt, est);
  EXPECT_EQ(error.matched_poses, static_cast<int>(gt.size()));
  EXPECT_LT(error.ate_rmse_m, 1e-9);
  EXPECT_LT(error.rpe_trans_per_s, 1e-9);
}

}  // namespace
}  // namespace sightmap::slam
