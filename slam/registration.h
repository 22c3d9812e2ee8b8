// Registration of two RGB-D frames from their features: nearest-neighbour-ratio matches, RANSAC
// over 3D-3D correspondences with a rigid (Kabsch) minimal solver, a weighted refinement on all
// inliers, and a dense verification that a wrong pose cannot pass on a handful of lucky inliers.
//
// Why the dense check: on real frames 48 cm and 32 degrees apart, a plain RANSAC with a 20-inlier
// minimum accepts a pose 65 cm wrong on 32 "inliers" (repeated texture agrees with itself). A wrong
// pose puts many of one frame's measured surfaces in front of surfaces the other camera saw
// through (free-space violations); a right pose makes the depth maps agree where they overlap.
#pragma once

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "slam/features.h"
#include "slam/matching.h"

namespace sightmap::slam {

struct RegistrationOptions {
  MatchOptions matching;

  // RANSAC.
  int ransac_max_iterations = 2000;
  double ransac_confidence = 0.999;
  uint64_t ransac_seed = 0x5eed;  // fixed: the same frames always give the same answer
  // A correspondence is an inlier when the aligned points are closer than
  // max(min_inlier_distance_m, inlier_sigmas x the combined depth noise of both points).
  double min_inlier_distance_m = 0.02;
  double inlier_sigmas = 3.0;
  // Axial depth noise sigma(z) = depth_noise_coeff x z^2 [1/m] (Kinect v1: Khoshelham & Elberink
  // 2012).
  double depth_noise_coeff = 1.425e-3;
  // Three sample points closer together than this give an ill-conditioned rotation [m].
  double min_sample_spread_m = 0.05;

  // Refinement on the symmetric reprojection error of the inliers (Gauss-Newton iterations, and
  // the Huber threshold [px] beyond which a residual's weight falls off).
  int refine_iterations = 10;
  double huber_px = 2.0;

  // Guided matching (0 radius turns it off): around where a rough pose puts each source point in
  // the target image [px], the nearest descriptor within guided_max_hamming [bits] of 256 that
  // passes the ratio test against its local runner-up. The rough pose comes from RANSAC on the
  // global matches when it has guided_min_seed_inliers, and from the caller's prior.
  double guided_radius_px = 24.0;
  int guided_max_hamming = 64;
  int guided_min_seed_inliers = 6;

  // Acceptance. 12 inliers, not the usual 20: the dense verification below is what refuses a wrong
  // pose (the lounge's 0->116 pose 65 cm off had 32 "inliers"), and at 1 Hz many right poses on
  // sparsely textured views have 12-20 (the simulator's walk: 58 segments in 200 keyframes at 12,
  // 66 at 20).
  int min_inliers = 12;
  double near_depth_m = 4.0;  // what RegistrationResult::near_inliers counts [m]
  // Inliers / correspondences with 3D points on both sides.
  double min_inlier_ratio = 0.15;

  // Dense verification (skipped when either depth image is empty): every verify_stride_px-th
  // pixel of each frame is moved into the other. Of those landing on a measured depth, the share
  // that agree (within max(verify_min_tolerance_m, inlier_sigmas x noise)) must reach
  // min_consistent_fraction, and the share lying in front of the other frame's surface must stay
  // below max_violation_fraction. Both directions are checked.
  int verify_stride_px = 4;
  double verify_min_tolerance_m = 0.03;
  double min_consistent_fraction = 0.5;
  double max_violation_fraction = 0.15;
  // Fewer overlapping samples than this cannot confirm a pose.
  int min_overlap_samples = 500;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const RegistrationOptions& options);
void from_json(const nlohmann::json& json, RegistrationOptions& options);

// Where the time of one registration went [s].
struct RegistrationTimes {
  double matching_s = 0.0;
  double ransac_s = 0.0;  // RANSAC and refinement
  double verification_s = 0.0;
};

struct RegistrationResult {
  bool success = false;
  std::string failure;  // why it was refused, when !success
  // Refused by the dense verification alone: the pose is the refined one on enough inliers (a
  // start for dense alignment, slam/dense_rescue.h).
  bool refused_by_verification = false;
  // Maps points of the source camera into the target camera (cam_target_from_cam_source).
  Eigen::Isometry3d target_from_source = Eigen::Isometry3d::Identity();
  int matches = 0;          // descriptor matches among keypoints with 3D points
  int correspondences = 0;  // matches with 3D points on both sides
  int inliers = 0;
  // Inliers whose target point lies within RegistrationOptions::near_depth_m: far points alone
  // cannot tell a sideways step from a turn.
  int near_inliers = 0;
  double rmse_m = 0.0;  // of the inliers after refinement
  // Dense verification, the worse of both directions (0 when skipped).
  double consistent_fraction = 0.0;
  double violation_fraction = 0.0;
  int overlap_samples = 0;
  // Information (inverse covariance) of target_from_source, parameters ordered as translation
  // (x, y, z) then a small rotation (x, y, z) applied on the left, as in Ceres' pose_graph_3d.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  RegistrationTimes times;
  bool guided = false;  // the pose came from guided matches
};

// `prior` (optional) is a guess of target_from_source, e.g. from the motion so far, that seeds
// guided matching.
// Registers `source` to `target`. Depth images (16-bit mm, registered, the size of the camera or
// that size divided by a whole factor, e.g. 160x120 nearest-neighbour samples of 640x480 kept per
// keyframe) enable the dense verification; `camera` is shared by both frames. Refusal is a result,
// not an exception; exceptions are for invalid options or inputs.
RegistrationResult RegisterRgbd(const Features& source, const Features& target,
                                const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
                                const Intrinsics& camera,
                                const RegistrationOptions& options = RegistrationOptions(),
                                const Eigen::Isometry3d* prior = nullptr);

// Dense verification of result->target_from_source (as RegisterRgbd's last step): each depth
// image's pixels moved into the other camera (both ways) must agree with the depth seen there, and
// not lie in front of it (space the other camera saw empty). Fills the result's consistent and
// violation fractions and overlap samples; returns the reason to refuse the pose, or "". Depth
// images as RegisterRgbd's; throws InvalidArgument for ones that do not fit the camera.
std::string VerifyByDepth(const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
                          const Intrinsics& camera, const RegistrationOptions& options,
                          RegistrationResult* result);

}  // namespace sightmap::slam
