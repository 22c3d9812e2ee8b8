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

#include <optional>
#include <string>
#include <vector>

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

// A frame a second after the last that features did not register (a pale poster filling the
// view, a 30-degree turn with a 0.4 m step): dense alignment started from the motion model turned
// about the camera's vertical axis by each of a range of offsets, checked as the rescue checks.
//
// Why: on the robot's 1 Hz walk (seed 11) 107 of 600 frames did not register, 65 of them at the
// head's full 30 deg/s pan; at the true pose nearly all of them agree densely (consistent 0.8-1.0,
// nothing seen through), but alignment converges only from within 2-10 degrees, and the motion
// model at the start of a pan is off by up to 30. An alignment whose geometry leaves a turn free
// (one wall) is not taken: the hand-held walk's first step (seed 11, a pale wall, a 30-degree
// turn) was otherwise taken degrees off (DenseSearch.TakesNothingWhereTheGeometryLeavesATurnFree).
//
// Off by default: the steps it finds are right (1 Hz walks, seeds 1, 3, 5, 7, 11, 23: every step
// found within 0.7 degrees, a few 6-25 cm off along a wall), but the 1 Hz maps do not yet gain
// from them: robot seeds 1 / 3 / 5 / 7 / 11 / 23 1.05 / 2.57 / 3.87 / 6.10 / 3.22 / 2.42 m ->
// 1.57 / 3.24 / 8.15 / 5.51 / 3.99 / 0.48 m, hand-held 0.329 / 0.082 / 0.130 / 0.114 / 0.065 /
// 0.085 m -> 0.332 / 0.086 / 0.106 / 0.111 / 0.074 / 2.53 m. In hand-held seed 23 the tracker's
// chain is better with it (frame 185 found where the motion model is 17 degrees off) and every
// link but one ends as accurate; the prior link from blind frame 190 to 191, 0.5 degrees off
// without the search, ends 47 degrees off: the map sets in two halves 45 degrees apart, joined by
// prior links only, and the turned half's axes priors fall outside their bound (README). Passing
// found frames to the mapper as registered (refined, bridging blind runs) instead: hand-held seed
// 1 7.08 m (a false loop 23 m off).
struct DenseSearchOptions {
  bool enabled = false;
  // Turns about the camera's y axis added to the motion model's guess, one alignment each (about
  // 15 ms each at 320x240) [deg].
  std::vector<double> yaw_offsets_deg = {0.0,  -5.0,  5.0,  -10.0, 10.0, -15.0, 15.0, -20.0,
                                         20.0, -25.0, 25.0, -30.0, 30.0, -35.0, 35.0};
  // Verified poses further apart than this in rotation: the frames are ambiguous, none is taken
  // [deg].
  double max_disagreement_deg = 3.0;
  // An alignment whose geometry leaves a turn free (FixesRotation with this ratio and lever) is
  // not taken [-], [m].
  double min_eigen_ratio = 0.01;
  double lever_m = 1.5;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const DenseSearchOptions& options);
void from_json(const nlohmann::json& json, DenseSearchOptions& options);

struct DenseSearchResult {
  Eigen::Isometry3d target_from_source = Eigen::Isometry3d::Identity();
  double consistent_fraction = 0.0;
  int verified = 0;  // seeds whose alignment passed the check
};

// Aligns `source` to `target` from `guess` (target_from_source) turned by each yaw offset, keeps
// the alignments that pass the strict check (rescue's fractions), and returns the most consistent
// one unless two of them disagree by more than max_disagreement_deg; nullopt when none passes.
std::optional<DenseSearchResult> SearchByDenseAlignment(
    const Eigen::Isometry3d& guess, const DenseAligner& aligner, DenseAligner::Frame& source,
    DenseAligner::Frame& target, const cv::Mat& source_depth_mm, const cv::Mat& target_depth_mm,
    const Intrinsics& camera, const RegistrationOptions& registration,
    const DenseRescueOptions& rescue, const DenseSearchOptions& options);

}  // namespace sightmap::slam
