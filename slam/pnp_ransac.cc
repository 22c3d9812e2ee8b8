#include "slam/pnp_ransac.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>

#include "core/check.h"

namespace sightmap::slam {

bool PnpRansacOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (max_iterations <= 0) return fail("max_iterations must be positive");
  if (!(reprojection_px > 0.0)) return fail("reprojection_px must be positive");
  if (!(confidence > 0.0 && confidence < 1.0)) return fail("confidence must lie in (0, 1)");
  return true;
}

int RansacIterations(double confidence, double outlier_share, int sample_size, int max_iterations) {
  SIGHTMAP_CHECK(sample_size > 0, "a RANSAC sample needs at least one point");
  const double p = std::clamp(confidence, 0.0, 1.0);
  const double ep = std::clamp(outlier_share, 0.0, 1.0);
  const double num = std::max(1.0 - p, DBL_MIN);
  const double denom = 1.0 - std::pow(1.0 - ep, sample_size);
  if (denom < DBL_MIN) return 0;
  const double log_num = std::log(num);
  const double log_denom = std::log(denom);
  if (log_denom >= 0.0 || -log_num >= max_iterations * (-log_denom)) return max_iterations;
  return cvRound(log_num / log_denom);
}

namespace {

constexpr int kSampleSize = 4;  // three points for P3P, the fourth picks among its poses
// A P3P pose puts its three points on their rays to rounding; a spurious one misses by pixels.
constexpr double kSolutionTolerancePxSq = 1e-2;

// A pose as RANSAC scores it: x_cam = rotation * x_world + translation.
struct CamFromWorld {
  cv::Matx33d rotation;
  cv::Vec3d translation;
};

// The correspondences as the samples and the scoring read them.
class Correspondences {
 public:
  Correspondences(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
                  const cv::Matx33d& camera)
      : object_(object), image_(image), camera_(camera) {
    bearings_.reserve(object.size());
    points_.reserve(object.size());
    for (size_t i = 0; i < object.size(); ++i) {
      const Eigen::Vector3d ray((image[i].x - camera(0, 2)) / camera(0, 0),
                                (image[i].y - camera(1, 2)) / camera(1, 1), 1.0);
      bearings_.push_back(ray.normalized());
      points_.emplace_back(object[i].x, object[i].y, object[i].z);
    }
  }

  size_t size() const { return object_.size(); }

  // The poses P3P finds from the sample's first three correspondences, the one that reprojects
  // all four best (OpenCV's AP3P keeps that one too); none for a degenerate sample.
  bool SolveSample(const std::array<int, kSampleSize>& sample, CamFromWorld* pose) const {
    const opengv::absolute_pose::CentralAbsoluteAdapter adapter(bearings_, points_);
    const opengv::transformations_t solutions = opengv::absolute_pose::p3p_kneip(
        adapter, static_cast<size_t>(sample[0]), static_cast<size_t>(sample[1]),
        static_cast<size_t>(sample[2]));
    double best_error = std::numeric_limits<double>::infinity();
    for (const opengv::transformation_t& world_from_cam : solutions) {
      if (!world_from_cam.allFinite()) continue;
      CamFromWorld candidate;
      const Eigen::Matrix3d rotation = world_from_cam.leftCols<3>().transpose();
      const Eigen::Vector3d translation = -rotation * world_from_cam.col(3);
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) candidate.rotation(r, c) = rotation(r, c);
        candidate.translation[r] = translation[r];
      }
      // Kneip's quartic hands back the real parts of complex roots too: poses that do not put
      // the three points on their rays, which the fourth could still prefer when it is an
      // outlier. AP3P returns real roots only.
      const double solved_error = SquaredError(candidate, sample[0]) +
                                  SquaredError(candidate, sample[1]) +
                                  SquaredError(candidate, sample[2]);
      if (solved_error > kSolutionTolerancePxSq) continue;
      const double error = solved_error + SquaredError(candidate, sample[3]);
      if (error < best_error) {
        best_error = error;
        *pose = candidate;
      }
    }
    return best_error < std::numeric_limits<double>::infinity();
  }

  // Marks the correspondences within `threshold_sq` [px^2] of their projection, tested in single
  // precision as OpenCV's RANSAC does, and returns how many.
  int FindInliers(const CamFromWorld& pose, float threshold_sq, std::vector<uchar>* mask) const {
    mask->resize(size());
    int count = 0;
    for (size_t i = 0; i < size(); ++i) {
      const cv::Point2d p = Project(pose, static_cast<int>(i));
      const float dx = image_[i].x - static_cast<float>(p.x);
      const float dy = image_[i].y - static_cast<float>(p.y);
      const bool inlier = dx * dx + dy * dy <= threshold_sq;
      (*mask)[i] = inlier ? 1 : 0;
      count += inlier ? 1 : 0;
    }
    return count;
  }

 private:
  double SquaredError(const CamFromWorld& pose, int index) const {
    const cv::Point2d p = Project(pose, index);
    const cv::Point2f& observed = image_[static_cast<size_t>(index)];
    return (p.x - observed.x) * (p.x - observed.x) + (p.y - observed.y) * (p.y - observed.y);
  }

  // projectPoints without distortion: a point behind the camera projects through it, as there.
  cv::Point2d Project(const CamFromWorld& pose, int index) const {
    const cv::Point3f& x = object_[static_cast<size_t>(index)];
    const cv::Vec3d c = pose.rotation * cv::Vec3d(x.x, x.y, x.z) + pose.translation;
    const double inv_z = c[2] != 0.0 ? 1.0 / c[2] : 1.0;
    return {camera_(0, 0) * c[0] * inv_z + camera_(0, 2),
            camera_(1, 1) * c[1] * inv_z + camera_(1, 2)};
  }

  const std::vector<cv::Point3f>& object_;
  const std::vector<cv::Point2f>& image_;
  cv::Matx33d camera_;
  opengv::bearingVectors_t bearings_;
  opengv::points_t points_;
};

// Four distinct indices below `count`, drawn as OpenCV's RANSAC draws them.
std::array<int, kSampleSize> DrawSample(int count, cv::RNG* rng) {
  std::array<int, kSampleSize> sample{};
  for (int i = 0; i < kSampleSize; ++i) {
    for (;;) {
      sample[static_cast<size_t>(i)] = rng->uniform(0, count);
      if (std::find(sample.begin(), sample.begin() + i, sample[static_cast<size_t>(i)]) ==
          sample.begin() + i) {
        break;
      }
    }
  }
  return sample;
}

void ToRvecTvec(const CamFromWorld& pose, cv::Vec3d* rvec, cv::Vec3d* tvec) {
  cv::Rodrigues(pose.rotation, *rvec);
  *tvec = pose.translation;
}

}  // namespace

PnpRansacResult SolvePnpRansac(const std::vector<cv::Point3f>& object,
                               const std::vector<cv::Point2f>& image, const cv::Matx33d& camera,
                               const PnpRansacOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(object.size() == image.size(), "PnP needs one image point per object point ("
                                                    << object.size() << " vs " << image.size()
                                                    << ")");
  PnpRansacResult result;
  const int count = static_cast<int>(object.size());
  if (count < kSampleSize) return result;
  const Correspondences correspondences(object, image, camera);
  CamFromWorld pose;
  if (count == kSampleSize) {
    if (!correspondences.SolveSample({0, 1, 2, 3}, &pose)) return result;
    result.found = true;
    ToRvecTvec(pose, &result.rvec, &result.tvec);
    result.inliers = {0, 1, 2, 3};
    result.samples = 1;
    return result;
  }

  // OpenCV's seed, so the same correspondences draw the same samples as its solvePnPRansac.
  cv::RNG rng(static_cast<uint64>(-1));
  const auto threshold_sq = static_cast<float>(options.reprojection_px * options.reprojection_px);
  std::vector<uchar> mask;
  std::vector<uchar> best_mask;
  int best_count = 0;
  int iterations = options.max_iterations;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const std::array<int, kSampleSize> sample = DrawSample(count, &rng);
    ++result.samples;
    if (!correspondences.SolveSample(sample, &pose)) continue;
    const int good = correspondences.FindInliers(pose, threshold_sq, &mask);
    if (good > std::max(best_count, kSampleSize - 1)) {
      std::swap(mask, best_mask);
      best_count = good;
      iterations = RansacIterations(options.confidence, static_cast<double>(count - good) / count,
                                    kSampleSize, iterations);
    }
  }
  if (best_count == 0) return result;

  std::vector<cv::Point3d> object_inliers;
  std::vector<cv::Point2d> image_inliers;
  for (int i = 0; i < count; ++i) {
    if (!best_mask[static_cast<size_t>(i)]) continue;
    result.inliers.push_back(i);
    object_inliers.emplace_back(object[static_cast<size_t>(i)]);
    image_inliers.emplace_back(image[static_cast<size_t>(i)]);
  }
  // As OpenCV: the answer is EPnP on the best sample's inliers, not the sample's own pose.
  if (!cv::solvePnP(object_inliers, image_inliers, camera, cv::noArray(), result.rvec, result.tvec,
                    false, cv::SOLVEPNP_EPNP)) {
    result.inliers.clear();
    return result;
  }
  result.found = true;
  return result;
}

}  // namespace sightmap::slam
