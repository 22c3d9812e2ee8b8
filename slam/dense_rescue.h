// A features' pose that registration's dense check refused, aligned densely from where it stands
// and checked again.
//
// Why: with depth to 8 m, frames a second apart register largely on far keypoints whose depth errs
// by 5-9 cm, and RANSAC's inliers (within 3 sigma of that noise) admit poses 10-20 cm and 1-3
// degrees off, which the dense check rightly refuses. On the 1 Hz hand-held walk (seed 23) 43 of
// the 130 consecutive pairs registration refused were refused by that check alone, some on 150-190
// inliers; dense alignment (point-to-plane ICP and photometric error) started at their pose ended
// within 6 mm for most. What stays wrong after it (a repeated texture 0.2-0.6 m along, a slide
// along a wall) still shows surfaces that one camera saw through, so the second check is strict
// about those and lenient about agreement: a right pose at a second's distance often pairs only
// 30-50% of the pixels (the rest occluded or out of the other's range) but puts almost none in
// front of the other's surface.
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "slam/dense_alignment.h"
#include "slam/registration.h"

namespace sightmap::slam {

struct DenseRescueOptions {
  bool enabled = true;
  // Also an accepted registration that saw through more of the other frame's surface than
  // max_violation_fraction allows is aligned and checked again, and refused when that fails.
  bool check_accepted = true;
  // The check after alignment (RegistrationOptions' verification, these two fractions replaced):
  // measured on the 1 Hz hand-held walks (seeds 7, 11, 23), right poses after alignment put 0-1%
  // of their samples in front of the other frame's surface, wrong ones 7-69% [-].
  double min_consistent_fraction = 0.3;
  double max_violation_fraction = 0.02;
  // Alignment that moves the features' pose further than this found another basin [m], [deg].
  double max_correction_m = 0.5;
  double max_correction_deg = 10.0;
  // The floor of the rescued pose's covariance, added to the inverse of the alignment's
  // point-to-plane information (which leaves a slide along a bare wall free) [m], [rad].
  double min_sigma_m = 0.005;
  double min_sigma_rad = 0.002;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const DenseRescueOptions& options);
void from_json(const nlohmann::json& json, DenseRescueOptions& options);

// Whether RescueByDenseAlignment acts on `result`: with the options enabled, a registration
// refused by the dense check alone, or (check_accepted) accepted with more than
// max_violation_fraction of its samples seen through.
bool NeedsDenseAlignment(const RegistrationResult& result, const DenseRescueOptions& options);

// Aligns `source` to `target` densely from `refused`'s pose (one NeedsDenseAlignment picks) and
// verifies the result by depth (depth images as RegisterRgbd's,
// `registration` as it was registered with). Returns a successful result with the aligned pose, the
// alignment's information (floored) and the new verification figures; otherwise `refused` with its
// failure extended by why the rescue failed (an accepted registration that fails is refused). Does
// nothing (returns `refused`) unless NeedsDenseAlignment. `aligner` made the prepared frames.
RegistrationResult RescueByDenseAlignment(const RegistrationResult& refused,
                                          const DenseAligner& aligner, DenseAligner::Frame& source,
                                          DenseAligner::Frame& target,
                                          const cv::Mat& source_depth_mm,
                                          const cv::Mat& target_depth_mm, const Intrinsics& camera,
                                          const RegistrationOptions& registration,
                                          const DenseRescueOptions& options);

}  // namespace sightmap::slam
