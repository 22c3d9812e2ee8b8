#include "slam/pnp_ransac.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "core/check.h"

namespace sightmap::slam {
namespace {

const cv::Matx33d kCamera(525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0);

// Correspondences seen by a camera at a random pose: `count` points 1-8 m in front of it, the
// first `inliers` of them projected with `noise_px` of noise, the others at random pixels.
struct Problem {
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
};

Problem MakeProblem(int count, int inliers, double noise_px, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  Problem problem;
  problem.rvec = cv::Vec3d(unit(rng), unit(rng), unit(rng)) * 1.5;
  problem.tvec = cv::Vec3d(unit(rng), unit(rng), unit(rng)) * 3.0;
  cv::Matx33d rotation;
  cv::Rodrigues(problem.rvec, rotation);
  for (int i = 0; i < count; ++i) {
    // A point in the camera's view, moved to the world by the inverse pose.
    const double depth = 1.0 + 3.5 * (unit(rng) + 1.0);
    const cv::Vec3d cam((unit(rng) * 320.0) / 525.0 * depth, (unit(rng) * 240.0) / 525.0 * depth,
                        depth);
    const cv::Vec3d world = rotation.t() * (cam - problem.tvec);
    problem.object.emplace_back(static_cast<float>(world[0]), static_cast<float>(world[1]),
                                static_cast<float>(world[2]));
    if (i < inliers) {
      problem.image.emplace_back(static_cast<float>(525.0 * cam[0] / cam[2] + 319.5 + noise(rng)),
                                 static_cast<float>(525.0 * cam[1] / cam[2] + 239.5 + noise(rng)));
    } else {
      problem.image.emplace_back(static_cast<float>(320.0 + 320.0 * unit(rng)),
                                 static_cast<float>(240.0 + 240.0 * unit(rng)));
    }
  }
  return problem;
}

double PositionError(const Problem& problem, const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  cv::Matx33d truth;
  cv::Matx33d found;
  cv::Rodrigues(problem.rvec, truth);
  cv::Rodrigues(rvec, found);
  return cv::norm(truth.t() * problem.tvec - found.t() * tvec);  // camera centres [m]
}

TEST(PnpRansac, FindsThePoseAmongOutliers) {
  const Problem problem = MakeProblem(300, 120, 0.5, 7);  // 60% outliers
  PnpRansacOptions options;
  options.reprojection_px = 4.0;
  const PnpRansacResult result = SolvePnpRansac(problem.object, problem.image, kCamera, options);
  ASSERT_TRUE(result.found);
  EXPECT_LT(PositionError(problem, result.rvec, result.tvec), 0.02);
  int true_inliers = 0;
  for (int i : result.inliers) true_inliers += i < 120 ? 1 : 0;
  EXPECT_GE(true_inliers, 115);
  EXPECT_LE(result.inliers.size() - static_cast<size_t>(true_inliers), 3u);  // outliers by chance
  // The adaptive count stopped well before the cap: 40% inliers need ~270 samples at 0.999.
  EXPECT_LT(result.samples, options.max_iterations);
}

// The claim the locator rests on: OpenCV's solvePnPRansac with AP3P, the same samples drawn, ends
// with the same inliers and pose on most problems; where a sample's P3P differs (AP3P misses some
// all-inlier samples' pose, Kneip's is exact to rounding) ours mostly ends with more inliers.
// Measured on 1,000 such problems: 954 the same, 38 more, 5 as many, 3 fewer.
TEST(PnpRansac, AgreesWithOpenCvsSolvePnPRansac) {
  int same = 0;
  int more = 0;
  int fewer = 0;
  const int kProblems = 200;
  for (int k = 0; k < kProblems; ++k) {
    const int count = 12 + 37 * k % 400;
    const int inliers = std::max(6, count * (15 + 13 * k % 80) / 100);
    const Problem problem = MakeProblem(count, inliers, 0.8, 100u + static_cast<unsigned>(k));
    PnpRansacOptions options;
    options.reprojection_px = 4.0;
    const PnpRansacResult ours = SolvePnpRansac(problem.object, problem.image, kCamera, options);
    cv::Vec3d rvec;
    cv::Vec3d tvec;
    std::vector<int> inliers_cv;
    const bool found_cv = cv::solvePnPRansac(problem.object, problem.image, kCamera, cv::noArray(),
                                             rvec, tvec, false, options.max_iterations, 4.0f,
                                             options.confidence, inliers_cv, cv::SOLVEPNP_AP3P);
    if (ours.found == found_cv && ours.inliers == inliers_cv) {
      ++same;
      if (found_cv) {
        EXPECT_LT(cv::norm(ours.rvec - rvec) + cv::norm(ours.tvec - tvec), 1e-6) << "problem " << k;
      }
    } else if (ours.inliers.size() > inliers_cv.size()) {
      ++more;
    } else if (ours.inliers.size() < inliers_cv.size()) {
      ++fewer;
    }
  }
  EXPECT_GE(same, 185);  // 190 measured
  EXPECT_GE(more, 5);    // 8
  EXPECT_LE(fewer, 2);   // 1
}

TEST(PnpRansac, FourCorrespondencesAreTheirOwnPose) {
  const Problem problem = MakeProblem(4, 4, 0.0, 3);
  const PnpRansacResult result =
      SolvePnpRansac(problem.object, problem.image, kCamera, PnpRansacOptions());
  ASSERT_TRUE(result.found);
  EXPECT_EQ(result.inliers, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_LT(PositionError(problem, result.rvec, result.tvec), 1e-3);
}

TEST(PnpRansac, TooFewOrMismatchedCorrespondences) {
  const Problem problem = MakeProblem(3, 3, 0.0, 4);
  EXPECT_FALSE(SolvePnpRansac(problem.object, problem.image, kCamera, PnpRansacOptions()).found);
  std::vector<cv::Point2f> short_image(problem.image.begin(), problem.image.begin() + 2);
  EXPECT_THROW(SolvePnpRansac(problem.object, short_image, kCamera, PnpRansacOptions()), Error);
}

TEST(PnpRansac, OptionsCheckRejectsNonsense) {
  std::string error;
  EXPECT_TRUE(PnpRansacOptions().Check(&error)) << error;
  PnpRansacOptions options;
  options.max_iterations = 0;
  EXPECT_FALSE(options.Check(&error));
  options = PnpRansacOptions();
  options.reprojection_px = 0.0;
  EXPECT_FALSE(options.Check(&error));
  options = PnpRansacOptions();
  options.confidence = 1.0;
  EXPECT_FALSE(options.Check(&error));
}

TEST(RansacIterations, FollowsTheOutlierShare) {
  // log(0.001) / log(1 - 0.5^4) = 107.03.
  EXPECT_EQ(RansacIterations(0.999, 0.5, 4, 500), 107);
  EXPECT_EQ(RansacIterations(0.999, 0.9, 4, 500), 500);  // capped
  EXPECT_EQ(RansacIterations(0.999, 0.0, 4, 500), 0);    // no outliers: done
  EXPECT_EQ(RansacIterations(0.999, 0.5, 4, 50), 50);    // never above the count so far
}

}  // namespace
}  // namespace sightmap::slam
