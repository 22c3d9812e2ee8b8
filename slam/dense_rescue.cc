#include "slam/dense_rescue.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "slam/pose_graph.h"

namespace sightmap::slam {

namespace {

// Registration's verification with the rescue's fractions: strict about surfaces seen through,
// lenient about agreement.
RegistrationOptions StrictVerification(const RegistrationOptions& registration,
                                       const DenseRescueOptions& rescue) {
  RegistrationOptions strict = registration;
  strict.min_consistent_fraction = rescue.min_consistent_fraction;
  strict.max_violation_fraction = rescue.max_violation_fraction;
  return strict;
}

}  // namespace

bool DenseRescueOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!(min_consistent_fraction >= 0.0 && min_consistent_fraction <= 1.0) ||
      !(max_violation_fraction >= 0.0 && max_violation_fraction <= 1.0)) {
    return fail("dense rescue: verification fractions must be in [0, 1]");
  }
  if (!(max_correction_m > 0.0) || !(max_correction_deg > 0.0)) {
    return fail("dense rescue: max_correction_m and max_correction_deg must be positive");
  }
  if (!(min_sigma_m > 0.0) || !(min_sigma_rad > 0.0)) {
    return fail("dense rescue: min_sigma_m and min_sigma_rad must be positive");
  }
  return true;
}

bool NeedsDenseAlignment(const RegistrationResult& result, const DenseRescueOptions& options) {
  return options.enabled && (result.refused_by_verification ||
                             (options.check_accepted && result.success &&
                              result.violation_fraction > options.max_violation_fraction));
}

RegistrationResult RescueByDenseAlignment(const RegistrationResult& refused,
                                          const DenseAligner& aligner, DenseAligner::Frame& source,
                                          DenseAligner::Frame& target,
                                          const cv::Mat& source_depth_mm,
                                          const cv::Mat& target_depth_mm, const Intrinsics& camera,
                                          const RegistrationOptions& registration,
                                          const DenseRescueOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  if (!NeedsDenseAlignment(refused, options)) return refused;
  RegistrationResult rescued = refused;
  const auto give_up = [&refused](const std::string& why) {
    RegistrationResult result = refused;
    if (result.success) {
      result.success = false;
      result.failure = "the features' pose saw through " +
                       std::to_string(static_cast<int>(100 * refused.violation_fraction)) +
                       "% of the other frame's surface";
    }
    result.failure += "; dense alignment from it " + why;
    return result;
  };
  const DenseAlignment aligned = aligner.Align(source, target, refused.target_from_source);
  if (!aligned.success) return give_up("failed: " + aligned.failure);
  if (!MotionWithin(refused.target_from_source.inverse() * aligned.target_from_source,
                    options.max_correction_m, options.max_correction_deg)) {
    return give_up("moved beyond the rescue's bounds");
  }
  rescued.target_from_source = aligned.target_from_source;
  const RegistrationOptions strict = StrictVerification(registration, options);
  const std::string failure =
      VerifyByDepth(source_depth_mm, target_depth_mm, camera, strict, &rescued);
  if (!failure.empty()) return give_up("is refused too: " + failure);
  // Directions the geometry leaves free (a slide along a wall) stay free.
  rescued.information =
      FlooredInformation(aligned.information, options.min_sigma_m, options.min_sigma_rad);
  rescued.success = true;
  rescued.failure.clear();
  rescued.refused_by_verification = false;
  return rescued;
}

bool DenseSearchOptions::Check(std::string* error) const {
  if (yaw_offsets_deg.empty() || std::any_of(yaw_offsets_deg.begin(), yaw_offsets_deg.end(),
                                             [](double deg) { return !(std::abs(deg) <= 90.0); })) {
    if (error) *error = "dense search: yaw_offsets_deg must hold turns within +-90 degrees";
    return false;
  }
  if (!(max_disagreement_deg > 0.0) || !(min_eigen_ratio >= 0.0 && min_eigen_ratio <= 1.0) ||
      !(lever_m > 0.0)) {
    if (error) {
      *error =
          "dense search: max_disagreement_deg and lever_m must be positive, min_eigen_ratio in "
          "[0, 1]";
    }
    return false;
  }
  return true;
}

std::optional<DenseSearchResult> SearchByDenseAlignment(
    const Eigen::Isometry3d& guess, const DenseAligner& aligner, DenseAligner::Frame& source,
    DenseAligner::Frame& target, const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
    const Intrinsics& camera, const RegistrationOptions& registration,
    const DenseRescueOptions& rescue, const DenseSearchOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  const RegistrationOptions strict = StrictVerification(registration, rescue);
  std::vector<DenseSearchResult> verified;
  for (double yaw_deg : options.yaw_offsets_deg) {
    // The source camera turned about its own centre (a turn on the left keeps the centre).
    const Eigen::Isometry3d seed =
        Eigen::Isometry3d(Eigen::AngleAxisd(DegToRad(yaw_deg), Eigen::Vector3d::UnitY())) * guess;
    const DenseAlignment aligned = aligner.Align(source, target, seed);
    if (!aligned.success ||
        !FixesRotation(aligned.information, options.min_eigen_ratio, options.lever_m)) {
      continue;
    }
    RegistrationResult check;
    check.target_from_source = aligned.target_from_source;
    if (!VerifyByDepth(source_depth_mm, target_depth_mm, camera, strict, &check).empty()) continue;
    DenseSearchResult result;
    result.target_from_source = aligned.target_from_source;
    result.consistent_fraction = check.consistent_fraction;
    verified.push_back(result);
  }
  if (verified.empty()) return std::nullopt;
  const auto best = std::max_element(verified.begin(), verified.end(),
                                     [](const DenseSearchResult& a, const DenseSearchResult& b) {
                                       return a.consistent_fraction < b.consistent_fraction;
                                     });
  for (const DenseSearchResult& other : verified) {
    if (RotationAngleDeg(other.target_from_source.inverse() * best->target_from_source) >
        options.max_disagreement_deg) {
      return std::nullopt;
    }
  }
  DenseSearchResult result = *best;
  result.verified = static_cast<int>(verified.size());
  return result;
}

SIGHTMAP_OPTIONS_JSON(DenseSearchOptions, enabled, yaw_offsets_deg, max_disagreement_deg,
                      min_eigen_ratio, lever_m)

SIGHTMAP_OPTIONS_JSON(DenseRescueOptions, enabled, check_accepted, min_consistent_fraction,
                      max_violation_fraction, max_correction_m, max_correction_deg, min_sigma_m,
                      min_sigma_rad)

}  // namespace sightmap::slam
