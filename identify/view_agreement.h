// Stage 5c of Locate: does the model, seen from a pose, look like the photo?
//
// Why: PnP and its checks judge a pose by the features it explains. Where the building repeats a
// texture (the same poster in two rooms, the tile grid of a ceiling, a box printed on every face)
// a wrong pose explains dozens to hundreds of those features as well as the right one would; what
// differs is everything around them. So the verified keyframe's pixels, placed in 3D by its depth,
// are projected into the photo from the pose, and their grey levels compared with the photo's
// (zero-mean normalised cross-correlation: indifferent to the exposure and white balance of a
// phone against the sensor). A right pose lines up walls, edges and shading; a wrong one lines up
// the matched texture and little else. This is InLoc's dense pose verification (Taira et al.,
// CVPR 2018) done with the keyframe's own depth instead of a rendered model.
//
// Two figures, both must agree: the correlation over all projected pixels (a pose metres off
// correlates the photo with another room), and the median of the correlations within cells of an
// 8x8 grid over the photo (a pose one tile off on a ceiling grid lines up the tiles' overall
// shading but not the detail in each cell).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"

namespace sightmap::identify {

struct ViewAgreementOptions {
  // A keyframe is kept as a thumbnail this wide (grey, area-averaged; its depth sampled at the same
  // pixels, not averaged across depth edges); the photo is compared at photo_side_px on its longer
  // side [px].
  int thumbnail_width_px = 160;
  int photo_side_px = 320;
  // Keyframe depth used [m]: nearer is not measured, farther too noisy to place a pixel.
  double min_depth_m = 0.2;
  double max_depth_m = 6.0;
  // A keyframe pixel hidden behind another one landing in the same z-buffer cell of this size (in
  // photo pixels at photo_side_px), farther by more than occlusion_margin_ratio of its depth, is
  // not compared [px], [].
  int zbuffer_cell_px = 4;
  double occlusion_margin_ratio = 0.05;
  // A cell of the 8x8 grid counts when it holds this many compared pixels and both its keyframe
  // and photo grey levels vary by at least min_cell_std (a bare patch correlates with anything)
  // [pixels], [grey levels].
  int min_cell_samples = 15;
  double min_cell_std = 4.0;
  // Too little overlap to judge: fewer compared pixels or counted cells than these.
  int min_samples = 200;
  int min_cells = 3;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const ViewAgreementOptions& options);
void from_json(const nlohmann::json& json, ViewAgreementOptions& options);

// A keyframe as the check needs it: small grey image, depth at the same pixels, the camera at
// that size.
struct KeyframeThumbnail {
  cv::Mat grey;      // CV_8UC1
  cv::Mat depth_mm;  // CV_16UC1, the same size; 0 where not measured
  Intrinsics intrinsics;
  size_t Bytes() const;
};
// From the keyframe's colour (BGR) or grey image at any size and its depth [mm] at the
// intrinsics' size; throws InvalidArgument on empty or mismatched images.
KeyframeThumbnail MakeThumbnail(const cv::Mat& color_or_grey, const cv::Mat& depth_mm,
                                const Intrinsics& intrinsics, const ViewAgreementOptions& options);

// The photo as compared: grey, photo_side_px on its longer side, lightly blurred (CV_32F).
cv::Mat AgreementImage(const cv::Mat& photo, const ViewAgreementOptions& options);

struct ViewAgreement {
  bool judged = false;  // enough overlap to say: else the figures below are 0
  double global_ncc = 0.0;
  double cell_median_ncc = 0.0;
  int samples = 0;  // keyframe pixels compared
  int cells = 0;    // cells of the 8x8 grid counted
  // The smaller of the two correlations: what a threshold compares.
  double Score() const;
};
// The keyframe's pixels projected into the photo (`image`, from AgreementImage; `intrinsics` at
// the photo's full size or any other, scaled to the image) from `world_from_photo`, compared.
ViewAgreement MeasureViewAgreement(const cv::Mat& image, const Intrinsics& intrinsics,
                                   const Eigen::Isometry3d& world_from_photo,
                                   const KeyframeThumbnail& keyframe,
                                   const Eigen::Isometry3d& world_from_keyframe,
                                   const ViewAgreementOptions& options);

// A keyframe's thumbnail (not owned) and where the keyframe stood.
struct PlacedThumbnail {
  const KeyframeThumbnail* thumbnail = nullptr;
  Eigen::Isometry3d world_from_keyframe = Eigen::Isometry3d::Identity();
};
// The same with several keyframes' pixels projected at once, the nearest kept where they land on
// one z-buffer cell: where one keyframe saw past furniture that stands between the photo and the
// wall, another may have seen that furniture.
ViewAgreement MeasureViewAgreement(const cv::Mat& image, const Intrinsics& intrinsics,
                                   const Eigen::Isometry3d& world_from_photo,
                                   const std::vector<PlacedThumbnail>& keyframes,
                                   const ViewAgreementOptions& options);

}  // namespace sightmap::identify
