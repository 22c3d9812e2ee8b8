#include "identify/locator.h"

#include <sstream>

namespace sightmap {

const char* ToString(IntrinsicsSource source) {
  switch (source) {
    case IntrinsicsSource::kGiven:
      return "given";
    case IntrinsicsSource::kCalibration:
      return "calibration";
    case IntrinsicsSource::kExif:
      return "exif";
    case IntrinsicsSource::kEstimated:
      return "estimated";
  }
  return "unknown";
}

bool LocatorOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (!features.Check(error)) return false;
  if (max_image_side_px < 320) why << "max_image_side_px must be at least 320";
  else if (retrieval_candidates < 1) why << "retrieval_candidates must be at least 1";
  else if (neighbour_radius_m < 0.0 || max_neighbours < 0)
    why << "neighbour_radius_m and max_neighbours must not be negative";
  else if (!(match_ratio > 0.0 && match_ratio <= 1.0)) why << "match_ratio must be in (0, 1]";
  else if (!(pnp_reprojection_px > 0.0) || pnp_iterations < 1)
    why << "pnp_reprojection_px and pnp_iterations must be positive";
  else if (min_inliers < 4) why << "min_inliers must be at least 4 (PnP needs 4 points)";
  else if (!(max_rotation_from_keyframe_deg > 0.0 && max_rotation_from_keyframe_deg <= 180.0))
    why << "max_rotation_from_keyframe_deg must be in (0, 180]";
  else if (focal_candidates_35mm.empty()) why << "focal_candidates_35mm must not be empty";
  else if (!(occlusion_voxel_m > 0.0) || occlusion_downscale < 1)
    why << "occlusion_voxel_m and occlusion_downscale must be positive";
  else if (occlusion_margin_m < 0.0 || occlusion_margin_ratio < 0.0)
    why << "occlusion margins must not be negative";
  else if (!(min_in_view_share > 0.0 && min_in_view_share <= 1.0) ||
           !(min_unoccluded_share > 0.0 && min_unoccluded_share <= 1.0))
    why << "min_in_view_share and min_unoccluded_share must be in (0, 1]";
  for (double f : focal_candidates_35mm) {
    if (why.tellp() == 0 && !(f > 0.0)) why << "focal_candidates_35mm must be positive";
  }
  if (why.tellp() == 0) return true;
  if (error != nullptr) *error = "LocatorOptions: " + why.str();
  return false;
}

}  // namespace sightmap
