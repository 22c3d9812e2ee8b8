#include "slam/dense_rescue.h"

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "slam/pose_graph.h"

namespace sightmap::slam {

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
  RegistrationOptions strict = registration;
  strict.min_consistent_fraction = options.min_consistent_fraction;
  strict.max_violation_fraction = options.max_violation_fraction;
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

SIGHTMAP_OPTIONS_JSON(DenseRescueOptions, enabled, check_accepted, min_consistent_fraction,
                      max_violation_fraction, max_correction_m, max_correction_deg, min_sigma_m,
                      min_sigma_rad)

}  // namespace sightmap::slam
