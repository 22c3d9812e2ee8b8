#include "mapping/photo_features.h"

#include <vector>

#include "core/check.h"

namespace sightmap::mapping {

namespace {

Features WithPointsOnly(const Features& features) {
  Features kept;
  std::vector<int> rows;
  for (size_t i = 0; i < features.size(); ++i) {
    if (i < features.has_point.size() && features.has_point[i]) rows.push_back(static_cast<int>(i));
  }
  kept.descriptors.create(static_cast<int>(rows.size()), features.descriptors.cols,
                          features.descriptors.type());
  for (size_t k = 0; k < rows.size(); ++k) {
    const size_t i = static_cast<size_t>(rows[k]);
    kept.keypoints.push_back(features.keypoints[i]);
    kept.points_cam.push_back(features.points_cam[i]);
    kept.has_point.push_back(true);
    features.descriptors.row(rows[k]).copyTo(kept.descriptors.row(static_cast<int>(k)));
  }
  return kept;
}

}  // namespace

bool PhotoFeatureExtraction::Check(std::string* error) const {
  if (features.type != slam::FeatureOptions::Type::kSift || max_side_px < 320) {
    *error = "photo features must be of type \"sift\" at a side of at least 320 px";
    return false;
  }
  return features.Check(error);
}

Features ExtractPhotoFeatures(const cv::Mat& color, const cv::Mat& depth,
                              const Intrinsics& intrinsics,
                              const PhotoFeatureExtraction& extraction) {
  return WithPointsOnly(slam::ExtractFeaturesAtMostOfSide(
      color, depth, intrinsics, extraction.max_side_px, extraction.features));
}

int64_t AddMissingPhotoFeatures(store::Model* model, const PhotoFeatureExtraction& extraction,
                                const std::function<void(int64_t, int64_t)>& progress) {
  SIGHTMAP_CHECK(model != nullptr, "AddMissingPhotoFeatures needs a model");
  SIGHTMAP_CHECK_OPTIONS(extraction);
  std::vector<store::KeyframeInfo> missing;
  for (const store::KeyframeInfo& info : model->Keyframes()) {
    if (info.color_bytes > 0 && info.depth_bytes > 0 && !model->HasPhotoFeatures(info.id)) {
      missing.push_back(info);
    }
  }
  const int64_t total = static_cast<int64_t>(missing.size());
  int64_t done = 0;
  for (const store::KeyframeInfo& info : missing) {
    const cv::Mat color = model->LoadColor(info.id);
    const cv::Mat depth = model->LoadDepth(info.id);
    // A keyframe whose images disagree in size gets an empty row: it is not tried again.
    const Features features = color.size() == depth.size()
                                  ? ExtractPhotoFeatures(color, depth, info.intrinsics, extraction)
                                  : Features();
    model->SetPhotoFeatures(info.id, features);
    ++done;
    if (progress) progress(done, total);
  }
  return done;
}

}  // namespace sightmap::mapping
