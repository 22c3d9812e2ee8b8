#include "slam/registration.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "capture/rgbd_source.h"
#include "core/check.h"
#include "core/rotation.h"
#include "tests/test_data.h"

namespace sightmap::slam {
namespace {

// Source features at random points in front of the camera; the target sees the same points
// moved by `target_from_source`, plus `outliers` matches whose target point is somewhere else.
void SyntheticPair(const Eigen::Isometry3d& target_from_source, int inliers, int outliers,
                   double noise_m, Features* source, Features* target) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> lateral(-1.5, 1.5);
  std::uniform_real_distribution<double> depth(1.0, 4.0);
  std::normal_distribution<double> noise(0.0, noise_m);
  std::uniform_int_distribution<int> byte(0, 255);
  const int total = inliers + outliers;
  source->descriptors.create(total, 32, CV_8U);
  target->descriptors.create(total, 32, CV_8U);
  for (int i = 0; i < total; ++i) {
    for (int b = 0; b < 32; ++b) {
      source->descriptors.at<uint8_t>(i, b) = static_cast<uint8_t>(byte(rng));
    }
    source->descriptors.row(i).copyTo(target->descriptors.row(i));
    const Eigen::Vector3d point(lateral(rng), lateral(rng), depth(rng));
    Eigen::Vector3d seen = target_from_source * point;
    if (i >= inliers) seen = Eigen::Vector3d(lateral(rng), lateral(rng), depth(rng));
    seen += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    for (Features* features : {source, target}) {
      features->keypoints.emplace_back(cv::Point2f(0, 0), 31.0f);
      features->has_point.push_back(true);
    }
    source->points_cam.push_back(point);
    target->points_cam.push_back(seen);
  }
}

Eigen::Isometry3d Motion(double angle_rad, const Eigen::Vector3d& translation) {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() =
      Eigen::AngleAxisd(angle_rad, Eigen::Vector3d(0.1, 1.0, 0.2).normalized()).matrix();
  motion.translation() = translation;
  return motion;
}

TEST(Registration, RecoversAKnownMotionAmongFortyPercentOutliers) {
  const Eigen::Isometry3d truth = Motion(0.5, {0.4, -0.1, 0.3});
  Features source;
  Features target;
  SyntheticPair(truth, 300, 200, 0.003, &source, &target);
  const RegistrationResult result =
      RegisterRgbd(source, target, cv::Mat(), cv::Mat(), Intrinsics());
  ASSERT_TRUE(result.success) << result.failure;
  EXPECT_EQ(result.correspondences, 500);
  EXPECT_GE(result.inliers, 290);
  EXPECT_LE(result.inliers, 310);
  EXPECT_LT((result.target_from_source.translation() - truth.translation()).norm(), 0.005);
  EXPECT_LT(RotationAngleDeg(result.target_from_source.inverse() * truth), 0.2);
  // Six directions constrained by hundreds of points: the information is well conditioned.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(result.information);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0);
}

// The tracker keeps a keyframe while enough inliers lie near: far points alone cannot tell a
// sideways step from a turn.
TEST(Registration, CountsTheInliersThatLieNear) {
  const Eigen::Isometry3d truth = Motion(0.1, {0.2, 0.0, 0.1});
  Features source;
  Features target;
  SyntheticPair(truth, 300, 0, 0.003, &source, &target);
  int near_points = 0;  // target points within 2.5 m (depths 1-4 m, so about half)
  for (const Eigen::Vector3d& point : target.points_cam) near_points += point.z() <= 2.5 ? 1 : 0;
  const auto near_inliers = [&](double near_depth_m) {
    RegistrationOptions options;
    options.near_depth_m = near_depth_m;
    const RegistrationResult result =
        RegisterRgbd(source, target, cv::Mat(), cv::Mat(), Intrinsics(), options);
    EXPECT_TRUE(result.success) << result.failure;
    EXPECT_GE(result.inliers, 297);
    return result.near_inliers;
  };
  EXPECT_NEAR(near_inliers(2.5), near_points, 3);
  EXPECT_GT(near_points, 90);
  EXPECT_LT(near_points, 210);
  EXPECT_GE(near_inliers(100.0), 297);
  EXPECT_EQ(near_inliers(0.5), 0);
}

TEST(Registration, RefusesWhenOutliersDominate) {
  Features source;
  Features target;
  SyntheticPair(Motion(0.3, {0.2, 0.0, 0.1}), 10, 300, 0.003, &source, &target);
  const RegistrationResult result =
      RegisterRgbd(source, target, cv::Mat(), cv::Mat(), Intrinsics());
  EXPECT_FALSE(result.success);
  EXPECT_FALSE(result.failure.empty());
}

TEST(Registration, RefusesFramesWithoutDepth) {
  Features source;
  Features target;
  SyntheticPair(Motion(0.3, {0.2, 0.0, 0.1}), 100, 0, 0.0, &source, &target);
  std::fill(source.has_point.begin(), source.has_point.end(), false);
  const RegistrationResult result =
      RegisterRgbd(source, target, cv::Mat(), cv::Mat(), Intrinsics());
  EXPECT_FALSE(result.success);
  EXPECT_NE(result.failure.find("3D correspondences"), std::string::npos) << result.failure;
}

// Keypoints where `camera` sees each feature's point (the reprojection refinement reads them).
void ProjectKeypoints(const Intrinsics& camera, Features* features) {
  for (size_t i = 0; i < features->size(); ++i) {
    const Eigen::Vector2d pixel = camera.Project(features->points_cam[i]);
    features->keypoints[i].pt =
        cv::Point2f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
  }
}

// A wall facing the camera `z_m` away (0: nothing measured), as 16-bit depth [mm].
cv::Mat Wall(const Intrinsics& camera, double z_m) {
  return cv::Mat(camera.height, camera.width, CV_16UC1, cv::Scalar(z_m * 1000.0));
}

// The last stage: the features agree on a pose, and the depth images must agree with it too.
TEST(Registration, DenseVerificationRefusesAPoseTheDepthContradicts) {
  const Intrinsics camera = Intrinsics::FromPinhole(320, 240, 250.0, 250.0, 159.5, 119.5);
  const Eigen::Isometry3d truth = Motion(0.0, {0.1, 0.0, 0.0});  // a step sideways
  Features source;
  Features target;
  SyntheticPair(truth, 200, 0, 0.0, &source, &target);
  ProjectKeypoints(camera, &source);
  ProjectKeypoints(camera, &target);
  const cv::Mat wall = Wall(camera, 2.0);

  // A wall 2 m ahead stays 2 m ahead after a step sideways: every overlapping sample agrees.
  const RegistrationResult agreed = RegisterRgbd(source, target, wall, wall, camera);
  ASSERT_TRUE(agreed.success) << agreed.failure;
  EXPECT_LT((agreed.target_from_source.translation() - truth.translation()).norm(), 1e-3);
  EXPECT_GT(agreed.overlap_samples, 3000);  // of 80 x 60 samples, less the step's margin
  EXPECT_DOUBLE_EQ(agreed.consistent_fraction, 1.0);
  EXPECT_DOUBLE_EQ(agreed.violation_fraction, 0.0);

  // The target saw the wall at 3 m: the source's wall would stand in space the target saw empty.
  const RegistrationResult seen_through =
      RegisterRgbd(source, target, wall, Wall(camera, 3.0), camera);
  EXPECT_FALSE(seen_through.success);
  EXPECT_EQ(seen_through.failure, "depth maps disagree: 0% consistent, 100% seen through");
  EXPECT_EQ(seen_through.inliers, agreed.inliers);  // the features alone did not object

  // Nothing measured in the target: nothing confirms the pose.
  const RegistrationResult unconfirmed =
      RegisterRgbd(source, target, wall, Wall(camera, 0.0), camera);
  EXPECT_FALSE(unconfirmed.success);
  EXPECT_EQ(unconfirmed.failure, "too little overlap to verify (0 samples)");

  // Depth at a size the camera's does not divide into is an error, not a refusal.
  EXPECT_THROW(RegisterRgbd(source, target, cv::Mat(70, 70, CV_16UC1, cv::Scalar(2000)),
                            cv::Mat(70, 70, CV_16UC1, cv::Scalar(2000)), camera),
               Error);
}

// Real Kinect-class frames with ground truth good to about a centimetre (ARCHITECTURE.md and the
// data README): near pairs must register within 2 cm and 0.8 deg; far pairs within 5 cm and
// 2 deg, or be refused — never a wrong pose.
TEST(Registration, RealLoungeFramesRegisterOrAreRefusedNeverWrong) {
  SIGHTMAP_REQUIRE_SHARED_DATA(dir, "rgbd/3dmatch-lounge/seq-01");
  std::unique_ptr<capture::RgbdSource> source = capture::OpenSource("3dmatch:" + dir);
  const Intrinsics camera = source->metadata().intrinsics;
  std::vector<RgbdFrame> frames;
  std::vector<Features> features;
  while (auto frame = source->Next()) {
    features.push_back(ExtractFeatures(frame->color, frame->depth, camera));
    frames.push_back(std::move(*frame));
  }
  ASSERT_EQ(frames.size(), 5u);  // frames 0, 1, 2, 116, 422
  for (const Features& f : features) {
    EXPECT_GE(f.size(), 900u);
    EXPECT_GE(f.NumPoints(), 500u);
  }
  struct Pair {
    size_t target, source;
    bool must_register;
    double max_translation_m, max_rotation_deg;
  };
  const Pair pairs[] = {{0, 1, true, 0.02, 0.8},
                        {0, 2, true, 0.02, 0.8},
                        {0, 3, false, 0.05, 2.0},
                        {3, 4, false, 0.05, 2.0}};
  for (const Pair& pair : pairs) {
    const RgbdFrame& target = frames[pair.target];
    const RgbdFrame& src = frames[pair.source];
    const Eigen::Isometry3d truth = target.world_from_cam_gt->inverse() * *src.world_from_cam_gt;
    const RegistrationResult result =
        RegisterRgbd(features[pair.source], features[pair.target], src.depth, target.depth, camera);
    const Eigen::Isometry3d error = truth.inverse() * result.target_from_source;
    std::printf(
        "pair %zu->%zu: truth %.1f cm %.1f deg | %s, %d matches, %d corr, %d inliers, rmse %.1f "
        "mm, consistent %.2f, seen-through %.2f | error %.2f cm %.2f deg %s\n",
        pair.target, pair.source, 100 * truth.translation().norm(), RotationAngleDeg(truth),
        result.success ? "accepted" : "refused", result.matches, result.correspondences,
        result.inliers, 1000 * result.rmse_m, result.consistent_fraction, result.violation_fraction,
        100 * error.translation().norm(), RotationAngleDeg(error), result.failure.c_str());
    if (pair.must_register) {
      ASSERT_TRUE(result.success) << result.failure;
    }
    if (result.success) {
      EXPECT_LT(error.translation().norm(), pair.max_translation_m);
      EXPECT_LT(RotationAngleDeg(error), pair.max_rotation_deg);
    }
  }
}

}  // namespace
}  // namespace sightmap::slam
