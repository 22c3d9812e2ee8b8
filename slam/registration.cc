#include "slam/registration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <vector>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "core/timing.h"
#include "slam/hamming.h"
#include "slam/rigid_alignment.h"

namespace sightmap::slam {
namespace {

struct Correspondence {
  Eigen::Vector3d source;
  Eigen::Vector3d target;
  Eigen::Vector2d source_px;
  Eigen::Vector2d target_px;
  double tolerance_m;  // inlier distance for this pair
  double weight;       // 1 / combined variance, for the refinement
};

std::vector<int> RowsWithPoints(const Features& features) {
  std::vector<int> rows;
  rows.reserve(features.size());
  for (size_t i = 0; i < features.size(); ++i) {
    if (features.has_point[i]) rows.push_back(static_cast<int>(i));
  }
  return rows;
}

cv::Mat SelectRows(const cv::Mat& descriptors, const std::vector<int>& rows) {
  cv::Mat selected(static_cast<int>(rows.size()), descriptors.cols, descriptors.type());
  for (size_t i = 0; i < rows.size(); ++i) {
    descriptors.row(rows[i]).copyTo(selected.row(static_cast<int>(i)));
  }
  return selected;
}

double DepthSigma(double z, const RegistrationOptions& options) {
  return options.depth_noise_coeff * z * z;
}

std::vector<Correspondence> MakeCorrespondences(const Features& source, const Features& target,
                                                const std::vector<cv::DMatch>& matches,
                                                const RegistrationOptions& options) {
  std::vector<Correspondence> pairs;
  pairs.reserve(matches.size());
  for (const cv::DMatch& match : matches) {
    const auto s = static_cast<size_t>(match.queryIdx);
    const auto t = static_cast<size_t>(match.trainIdx);
    if (!source.has_point[s] || !target.has_point[t]) continue;
    const double sigma = std::hypot(DepthSigma(source.points_cam[s].z(), options),
                                    DepthSigma(target.points_cam[t].z(), options));
    const cv::Point2f& source_px = source.keypoints[s].pt;
    const cv::Point2f& target_px = target.keypoints[t].pt;
    pairs.push_back({source.points_cam[s], target.points_cam[t],
                     Eigen::Vector2d(source_px.x, source_px.y),
                     Eigen::Vector2d(target_px.x, target_px.y),
                     std::max(options.min_inlier_distance_m, options.inlier_sigmas * sigma),
                     1.0 / (sigma * sigma + 1e-6)});
  }
  return pairs;
}

std::vector<size_t> FindInliers(const std::vector<Correspondence>& pairs,
                                const Eigen::Isometry3d& target_from_source) {
  std::vector<size_t> inliers;
  for (size_t i = 0; i < pairs.size(); ++i) {
    if ((target_from_source * pairs[i].source - pairs[i].target).norm() < pairs[i].tolerance_m) {
      inliers.push_back(i);
    }
  }
  return inliers;
}

bool FitOn(const std::vector<Correspondence>& pairs, const std::vector<size_t>& subset,
           bool weighted, Eigen::Isometry3d* target_from_source) {
  std::vector<Eigen::Vector3d> src;
  std::vector<Eigen::Vector3d> dst;
  std::vector<double> weights;
  for (size_t i : subset) {
    src.push_back(pairs[i].source);
    dst.push_back(pairs[i].target);
    if (weighted) weights.push_back(pairs[i].weight);
  }
  return AlignRigid(src, dst, weights, target_from_source);
}

// A rigid motion keeps distances: a sample whose pairwise distances disagree cannot be all
// inliers, so it is skipped before solving.
bool SampleIsPlausible(const std::vector<Correspondence>& pairs, const size_t (&idx)[3],
                       const RegistrationOptions& options) {
  for (int a = 0; a < 3; ++a) {
    for (int b = a + 1; b < 3; ++b) {
      const Correspondence& p = pairs[idx[a]];
      const Correspondence& q = pairs[idx[b]];
      const double d_source = (p.source - q.source).norm();
      const double d_target = (p.target - q.target).norm();
      if (d_source < options.min_sample_spread_m) return false;
      if (std::abs(d_source - d_target) > p.tolerance_m + q.tolerance_m) return false;
    }
  }
  return true;
}

struct DenseAgreement {
  int samples = 0;
  int consistent = 0;
  int violations = 0;
};

// Moves every stride-th measured pixel of `from` into the `to` camera and compares depths there.
// `camera` is the depth images' camera (scaled when they are smaller than the colour camera) and
// `stride` is in their pixels.
DenseAgreement CompareDepth(const cv::Mat& from_depth, const cv::Mat& to_depth,
                            const Eigen::Isometry3d& to_from_from, const Intrinsics& camera,
                            int stride, const RegistrationOptions& options) {
  DenseAgreement agreement;
  for (int v = 0; v < from_depth.rows; v += stride) {
    for (int u = 0; u < from_depth.cols; u += stride) {
      const uint16_t z_mm = from_depth.at<uint16_t>(v, u);
      if (z_mm == 0) continue;
      const Eigen::Vector3d point = to_from_from * camera.Unproject(u, v, z_mm * 1e-3);
      if (point.z() <= 0.1) continue;
      const Eigen::Vector2d pixel = camera.Project(point);
      const int tu = static_cast<int>(std::lround(pixel.x()));
      const int tv = static_cast<int>(std::lround(pixel.y()));
      if (tu < 0 || tv < 0 || tu >= to_depth.cols || tv >= to_depth.rows) continue;
      const uint16_t observed_mm = to_depth.at<uint16_t>(tv, tu);
      if (observed_mm == 0) continue;
      const double observed = observed_mm * 1e-3;
      const double tolerance =
          std::max(options.verify_min_tolerance_m,
                   options.inlier_sigmas *
                       std::hypot(DepthSigma(observed, options), DepthSigma(point.z(), options)));
      ++agreement.samples;
      const double difference = point.z() - observed;
      if (std::abs(difference) <= tolerance) {
        ++agreement.consistent;
      } else if (difference < -tolerance) {
        // In front of a surface the other camera saw: the space was seen empty.
        ++agreement.violations;
      }
    }
  }
  return agreement;
}

// Refines target_from_source by Gauss-Newton on the symmetric reprojection error of the inliers
// (each 3D point projected into the other image, Huber-weighted). Keypoint positions are good to
// a pixel while depth errs by centimetres at a few metres, so this is what makes the pose
// accurate; the 3D fit only gets it close.
Eigen::Isometry3d RefineByReprojection(const std::vector<Correspondence>& pairs,
                                       const std::vector<size_t>& inliers, const Intrinsics& camera,
                                       Eigen::Isometry3d pose, const RegistrationOptions& options) {
  if (!(camera.fx > 0.0) || !(camera.fy > 0.0)) return pose;
  const auto projection_jacobian = [&camera](const Eigen::Vector3d& q) {
    Eigen::Matrix<double, 2, 3> d;
    d << camera.fx / q.z(), 0.0, -camera.fx * q.x() / (q.z() * q.z()), 0.0, camera.fy / q.z(),
        -camera.fy * q.y() / (q.z() * q.z());
    return d;
  };
  for (int iteration = 0; iteration < options.refine_iterations; ++iteration) {
    Eigen::Matrix<double, 6, 6> hessian = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
    const Eigen::Isometry3d inverse = pose.inverse();
    const auto accumulate = [&](const Eigen::Vector2d& residual,
                                const Eigen::Matrix<double, 2, 6>& jacobian) {
      const double norm = residual.norm();
      const double weight = norm <= options.huber_px ? 1.0 : options.huber_px / norm;
      hessian += weight * jacobian.transpose() * jacobian;
      gradient += weight * jacobian.transpose() * residual;
    };
    for (size_t i : inliers) {
      const Correspondence& pair = pairs[i];
      // Source point seen by the target camera.
      const Eigen::Vector3d in_target = pose * pair.source;
      if (in_target.z() > 0.1) {
        Eigen::Matrix<double, 3, 6> d_point;
        d_point.leftCols<3>().setIdentity();
        d_point.rightCols<3>() = -Skew(in_target);
        accumulate(camera.Project(in_target) - pair.target_px,
                   projection_jacobian(in_target) * d_point);
      }
      // Target point seen by the source camera: T^-1 exp(-delta) p.
      const Eigen::Vector3d in_source = inverse * pair.target;
      if (in_source.z() > 0.1) {
        Eigen::Matrix<double, 3, 6> d_point;
        d_point.leftCols<3>() = -inverse.linear();
        d_point.rightCols<3>() = inverse.linear() * Skew(pair.target);
        accumulate(camera.Project(in_source) - pair.source_px,
                   projection_jacobian(in_source) * d_point);
      }
    }
    const Eigen::Matrix<double, 6, 1> delta = hessian.ldlt().solve(-gradient);
    if (!delta.allFinite()) break;
    pose = ExpSe3(delta) * pose;
    if (delta.norm() < 1e-8) break;
  }
  return pose;
}

// RANSAC with an adaptive number of iterations over 3-point samples; returns the inliers of the
// best pose (empty when there are fewer than 3 pairs).
std::vector<size_t> Ransac(const std::vector<Correspondence>& pairs,
                           const RegistrationOptions& options, std::mt19937_64& rng,
                           Eigen::Isometry3d* best) {
  std::vector<size_t> best_inliers;
  if (pairs.size() < 3) return best_inliers;
  std::uniform_int_distribution<size_t> pick(0, pairs.size() - 1);
  int needed = options.ransac_max_iterations;
  for (int iteration = 0; iteration < needed; ++iteration) {
    size_t idx[3] = {pick(rng), pick(rng), pick(rng)};
    if (idx[0] == idx[1] || idx[0] == idx[2] || idx[1] == idx[2]) continue;
    if (!SampleIsPlausible(pairs, idx, options)) continue;
    Eigen::Isometry3d candidate;
    if (!FitOn(pairs, {idx[0], idx[1], idx[2]}, false, &candidate)) continue;
    std::vector<size_t> inliers = FindInliers(pairs, candidate);
    if (inliers.size() <= best_inliers.size()) continue;
    best_inliers = std::move(inliers);
    *best = candidate;
    const double ratio = static_cast<double>(best_inliers.size()) / pairs.size();
    const double all_good = std::pow(ratio, 3.0);
    if (all_good > 1.0 - 1e-12) break;
    const double adaptive = std::log(1.0 - options.ransac_confidence) / std::log(1.0 - all_good);
    needed = std::min(options.ransac_max_iterations, static_cast<int>(std::ceil(adaptive)));
  }
  return best_inliers;
}

// Matches each source keypoint with a 3D point to the target keypoints (with 3D points) within
// guided_radius_px of where `target_from_source` projects it, keeping the nearest descriptor when
// it is close enough and clearly better than the runner-up there; mutual best only.
// Comparing descriptors is most of its work: the popcnt clone serves CPUs with the instruction.
__attribute__((target_clones("popcnt", "default"))) std::vector<cv::DMatch> GuidedMatches(
    const Features& source, const Features& target, const Eigen::Isometry3d& target_from_source,
    const Intrinsics& camera, const RegistrationOptions& options) {
  std::vector<cv::DMatch> matches;
  // 256-bit binary descriptors (ORB) only; others keep the global matches.
  if (source.descriptors.type() != CV_8U || target.descriptors.type() != CV_8U ||
      source.descriptors.cols != 32 || target.descriptors.cols != 32) {
    return matches;
  }
  const double cell = std::max(8.0, options.guided_radius_px);
  const int cols = static_cast<int>(std::ceil(camera.width / cell)) + 1;
  const int rows = static_cast<int>(std::ceil(camera.height / cell)) + 1;
  std::vector<std::vector<int>> grid(static_cast<size_t>(cols * rows));
  for (size_t t = 0; t < target.size(); ++t) {
    if (!target.has_point[t]) continue;
    const cv::Point2f& pt = target.keypoints[t].pt;
    const int gx = std::clamp(static_cast<int>(pt.x / cell), 0, cols - 1);
    const int gy = std::clamp(static_cast<int>(pt.y / cell), 0, rows - 1);
    grid[static_cast<size_t>(gy * cols + gx)].push_back(static_cast<int>(t));
  }
  const double radius2 = options.guided_radius_px * options.guided_radius_px;
  std::vector<int> best_source_for_target(target.size(), -1);
  std::vector<int> best_distance_for_target(target.size(), 1 << 30);
  std::vector<cv::DMatch> candidates;
  for (size_t s = 0; s < source.size(); ++s) {
    if (!source.has_point[s]) continue;
    const Eigen::Vector3d in_target = target_from_source * source.points_cam[s];
    if (in_target.z() <= 0.1) continue;
    const Eigen::Vector2d px = camera.Project(in_target);
    if (px.x() < -options.guided_radius_px || px.y() < -options.guided_radius_px ||
        px.x() > camera.width + options.guided_radius_px ||
        px.y() > camera.height + options.guided_radius_px) {
      continue;
    }
    const int gx = static_cast<int>(px.x() / cell);
    const int gy = static_cast<int>(px.y() / cell);
    TwoNearest nearest;
    for (int y = gy - 1; y <= gy + 1; ++y) {
      for (int x = gx - 1; x <= gx + 1; ++x) {
        if (x < 0 || y < 0 || x >= cols || y >= rows) continue;
        for (int t : grid[static_cast<size_t>(y * cols + x)]) {
          const cv::Point2f& pt = target.keypoints[static_cast<size_t>(t)].pt;
          const double dx = pt.x - px.x();
          const double dy = pt.y - px.y();
          if (dx * dx + dy * dy > radius2) continue;
          nearest.Offer(t, Hamming256(source.descriptors.ptr<uint8_t>(static_cast<int>(s)),
                                      target.descriptors.ptr<uint8_t>(t)));
        }
      }
    }
    if (nearest.best < 0 || nearest.best_distance > options.guided_max_hamming) continue;
    if (nearest.best_distance >= options.matching.ratio * nearest.second_distance) continue;
    candidates.push_back(
        cv::DMatch(static_cast<int>(s), nearest.best, static_cast<float>(nearest.best_distance)));
    const size_t target_index = static_cast<size_t>(nearest.best);
    if (nearest.best_distance < best_distance_for_target[target_index]) {
      best_distance_for_target[target_index] = nearest.best_distance;
      best_source_for_target[target_index] = static_cast<int>(s);
    }
  }
  for (const cv::DMatch& match : candidates) {
    if (best_source_for_target[static_cast<size_t>(match.trainIdx)] == match.queryIdx) {
      matches.push_back(match);
    }
  }
  return matches;
}

// Descriptor matches between the keypoints of `source` and `target` that have 3D points (rows of
// the full feature sets). Only those can take part, so only those are matched: a frame has a few
// hundred of them among its 1,000 keypoints, and matching cost is quadratic.
std::vector<cv::DMatch> MatchKeypointsWithPoints(const Features& source, const Features& target,
                                                 const MatchOptions& options) {
  const std::vector<int> source_rows = RowsWithPoints(source);
  const std::vector<int> target_rows = RowsWithPoints(target);
  std::vector<cv::DMatch> matches =
      MatchDescriptors(SelectRows(source.descriptors, source_rows),
                       SelectRows(target.descriptors, target_rows), options);
  for (cv::DMatch& match : matches) {
    match.queryIdx = source_rows[static_cast<size_t>(match.queryIdx)];
    match.trainIdx = target_rows[static_cast<size_t>(match.trainIdx)];
  }
  return matches;
}

// A pose with the correspondences it was found on and its inliers among them.
struct PoseEstimate {
  Eigen::Isometry3d target_from_source = Eigen::Isometry3d::Identity();
  std::vector<Correspondence> pairs;
  std::vector<size_t> inliers;
  bool guided = false;  // the pairs came from guided matching
};

// RANSAC on the global matches' pairs, then guided matching: a rough pose (RANSAC's, or the
// caller's prior) predicts where each source point appears in the target image, and it is matched
// among the target keypoints near there only. Frames a second apart with motion blur and repeated
// texture keep few global ratio-test matches; the local search recovers many more, and RANSAC runs
// again on them. The estimate with the most inliers wins. Adds guided matching's time to
// `matching_s`.
PoseEstimate EstimatePose(const Features& source, const Features& target,
                          std::vector<Correspondence> pairs, const Intrinsics& camera,
                          const RegistrationOptions& options, const Eigen::Isometry3d* prior,
                          double* matching_s) {
  std::mt19937_64 rng(options.ransac_seed);
  PoseEstimate best;
  best.inliers = Ransac(pairs, options, rng, &best.target_from_source);
  best.pairs = std::move(pairs);
  if (!(options.guided_radius_px > 0.0)) return best;
  std::vector<Eigen::Isometry3d> seeds;
  if (static_cast<int>(best.inliers.size()) >= options.guided_min_seed_inliers) {
    seeds.push_back(best.target_from_source);
  }
  if (prior != nullptr) seeds.push_back(*prior);
  for (const Eigen::Isometry3d& seed : seeds) {
    const auto guided_start = std::chrono::steady_clock::now();
    std::vector<Correspondence> guided = MakeCorrespondences(
        source, target, GuidedMatches(source, target, seed, camera, options), options);
    *matching_s += SecondsSince(guided_start);
    Eigen::Isometry3d pose;
    std::vector<size_t> inliers = Ransac(guided, options, rng, &pose);
    if (inliers.size() > best.inliers.size()) {
      best.pairs = std::move(guided);
      best.inliers = std::move(inliers);
      best.target_from_source = pose;
      best.guided = true;
    }
  }
  return best;
}

// Fits the pose on all inliers, weighting near points (less depth noise) more, and takes the
// inliers of the fit, until the set settles (at most five rounds; a fit that loses inliers is not
// taken); then refines it by reprojection.
void RefineOnInliers(const Intrinsics& camera, const RegistrationOptions& options,
                     PoseEstimate* estimate) {
  for (int round = 0; round < 5; ++round) {
    Eigen::Isometry3d refined;
    if (!FitOn(estimate->pairs, estimate->inliers, true, &refined)) break;
    std::vector<size_t> inliers = FindInliers(estimate->pairs, refined);
    if (inliers.size() < estimate->inliers.size()) break;
    const bool settled = inliers == estimate->inliers;
    estimate->target_from_source = refined;
    estimate->inliers = std::move(inliers);
    if (settled) break;
  }
  estimate->target_from_source = RefineByReprojection(estimate->pairs, estimate->inliers, camera,
                                                      estimate->target_from_source, options);
}

// The result's pose, inlier counts, RMSE and information (each inlier's point-to-point Jacobian
// weighted by its inverse depth variance).
void MeasureInliers(const PoseEstimate& estimate, const RegistrationOptions& options,
                    RegistrationResult* result) {
  const Eigen::Isometry3d& pose = estimate.target_from_source;
  result->target_from_source = pose;
  result->inliers = static_cast<int>(estimate.inliers.size());
  double squared = 0.0;
  for (size_t i : estimate.inliers) {
    const Correspondence& pair = estimate.pairs[i];
    if (pair.target.z() <= options.near_depth_m) ++result->near_inliers;
    const Eigen::Vector3d moved = pose * pair.source;
    squared += (moved - pair.target).squaredNorm();
    Eigen::Matrix<double, 3, 6> jacobian;
    jacobian.leftCols<3>().setIdentity();
    jacobian.rightCols<3>() = -Skew(moved);
    result->information += pair.weight * jacobian.transpose() * jacobian;
  }
  result->rmse_m = std::sqrt(squared / estimate.inliers.size());
}

}  // namespace

// Dense verification of the result's pose: each depth image's pixels moved into the other camera
// (both ways) must agree with the depth seen there, and not lie in front of it (space the other
// camera saw empty). Fills the result's figures; the reason to refuse, or empty.
std::string VerifyByDepth(const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
                          const Intrinsics& camera, const RegistrationOptions& options,
                          RegistrationResult* result) {
  SIGHTMAP_CHECK(source_depth_mm.type() == CV_16UC1 && target_depth_mm.type() == CV_16UC1 &&
                     source_depth_mm.cols > 0 && camera.width % source_depth_mm.cols == 0 &&
                     camera.height % source_depth_mm.rows == 0 &&
                     camera.width / source_depth_mm.cols == camera.height / source_depth_mm.rows &&
                     target_depth_mm.size() == source_depth_mm.size(),
                 "registration needs 16-bit depth images of the camera's size, or that size "
                 "divided by a whole factor");
  const int factor = camera.width / source_depth_mm.cols;
  const Intrinsics depth_camera =
      factor == 1 ? camera : camera.Scaled(source_depth_mm.cols, source_depth_mm.rows);
  const int stride = std::max(1, options.verify_stride_px / factor);
  const Eigen::Isometry3d& pose = result->target_from_source;
  const DenseAgreement forward =
      CompareDepth(source_depth_mm, target_depth_mm, pose, depth_camera, stride, options);
  const DenseAgreement backward =
      CompareDepth(target_depth_mm, source_depth_mm, pose.inverse(), depth_camera, stride, options);
  result->overlap_samples = std::min(forward.samples, backward.samples);
  const auto fraction = [](int part, int whole) {
    return whole > 0 ? static_cast<double>(part) / whole : 0.0;
  };
  result->consistent_fraction = std::min(fraction(forward.consistent, forward.samples),
                                         fraction(backward.consistent, backward.samples));
  result->violation_fraction = std::max(fraction(forward.violations, forward.samples),
                                        fraction(backward.violations, backward.samples));
  if (result->overlap_samples < options.min_overlap_samples) {
    return "too little overlap to verify (" + std::to_string(result->overlap_samples) + " samples)";
  }
  if (result->violation_fraction > options.max_violation_fraction ||
      result->consistent_fraction < options.min_consistent_fraction) {
    return "depth maps disagree: " +
           std::to_string(static_cast<int>(100 * result->consistent_fraction)) + "% consistent, " +
           std::to_string(static_cast<int>(100 * result->violation_fraction)) + "% seen through";
  }
  return "";
}

bool RegistrationOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!matching.Check(error)) return false;
  if (ransac_max_iterations <= 0) return fail("ransac_max_iterations must be positive");
  if (!(ransac_confidence > 0.0 && ransac_confidence < 1.0)) {
    return fail("ransac_confidence must be in (0, 1)");
  }
  if (!(min_inlier_distance_m > 0.0) || !(inlier_sigmas > 0.0) || depth_noise_coeff < 0.0) {
    return fail("inlier distances and noise must be positive");
  }
  if (min_inliers < 3) return fail("min_inliers must be at least 3");
  if (!(near_depth_m > 0.0)) return fail("near_depth_m must be positive");
  if (guided_radius_px < 0.0 || guided_max_hamming < 0 || guided_min_seed_inliers < 3) {
    return fail("guided matching needs a radius >= 0, a distance >= 0 and a seed of >= 3 inliers");
  }
  if (min_inlier_ratio < 0.0 || min_inlier_ratio > 1.0) {
    return fail("min_inlier_ratio must be in [0, 1]");
  }
  if (verify_stride_px <= 0 || !(verify_min_tolerance_m > 0.0)) {
    return fail("verify_stride_px and verify_min_tolerance_m must be positive");
  }
  if (min_consistent_fraction < 0.0 || min_consistent_fraction > 1.0 ||
      max_violation_fraction < 0.0 || max_violation_fraction > 1.0) {
    return fail("verification fractions must be in [0, 1]");
  }
  return true;
}

RegistrationResult RegisterRgbd(const Features& source, const Features& target,
                                const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
                                const Intrinsics& camera, const RegistrationOptions& options,
                                const Eigen::Isometry3d* prior) {
  SIGHTMAP_CHECK_OPTIONS(options);
  using Clock = std::chrono::steady_clock;
  RegistrationResult result;
  auto stage_start = Clock::now();
  const std::vector<cv::DMatch> matches =
      MatchKeypointsWithPoints(source, target, options.matching);
  result.matches = static_cast<int>(matches.size());
  std::vector<Correspondence> pairs = MakeCorrespondences(source, target, matches, options);
  result.times.matching_s = SecondsSince(stage_start);

  stage_start = Clock::now();
  PoseEstimate estimate = EstimatePose(source, target, std::move(pairs), camera, options, prior,
                                       &result.times.matching_s);
  result.guided = estimate.guided;
  result.correspondences = static_cast<int>(estimate.pairs.size());
  if (result.correspondences < options.min_inliers) {
    result.failure = "too few 3D correspondences (" + std::to_string(result.correspondences) + ")";
    return result;
  }
  if (static_cast<int>(estimate.inliers.size()) < options.min_inliers) {
    result.inliers = static_cast<int>(estimate.inliers.size());
    result.failure = "too few RANSAC inliers (" + std::to_string(result.inliers) + " of " +
                     std::to_string(result.correspondences) + ")";
    return result;
  }
  RefineOnInliers(camera, options, &estimate);
  MeasureInliers(estimate, options, &result);
  result.times.ransac_s = SecondsSince(stage_start);
  if (result.inliers < options.min_inliers) {
    result.failure = "too few inliers after refinement (" + std::to_string(result.inliers) + ")";
    return result;
  }
  const double ratio = static_cast<double>(result.inliers) / result.correspondences;
  if (ratio < options.min_inlier_ratio) {
    result.failure = "inlier ratio " + std::to_string(ratio) + " below " +
                     std::to_string(options.min_inlier_ratio);
    return result;
  }

  if (!source_depth_mm.empty() && !target_depth_mm.empty()) {
    stage_start = Clock::now();
    result.failure = VerifyByDepth(source_depth_mm, target_depth_mm, camera, options, &result);
    result.times.verification_s = SecondsSince(stage_start);
    if (!result.failure.empty()) {
      result.refused_by_verification = true;
      return result;
    }
  }
  result.success = true;
  return result;
}

SIGHTMAP_OPTIONS_JSON(RegistrationOptions, matching, ransac_max_iterations, ransac_confidence,
                      ransac_seed, min_inlier_distance_m, inlier_sigmas, depth_noise_coeff,
                      min_sample_spread_m, refine_iterations, huber_px, guided_radius_px,
                      guided_max_hamming, guided_min_seed_inliers, min_inliers, near_depth_m,
                      min_inlier_ratio, verify_stride_px, verify_min_tolerance_m,
                      min_consistent_fraction, max_violation_fraction, min_overlap_samples)

}  // namespace sightmap::slam
