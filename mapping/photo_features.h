// The features a phone photo is matched with (identify/locator.h): RootSIFT per keyframe, stored
// beside the ORB features SLAM uses. `sightmap map` extracts them as it writes each keyframe; a
// model mapped before they existed gets them from AddMissingPhotoFeatures (`sightmap info
// --upgrade`), so the locator does not extract them each time it loads.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/features.h"
#include "slam/features.h"
#include "store/model.h"

namespace sightmap::mapping {

struct PhotoFeatureExtraction {
  slam::FeatureOptions features = slam::RootSiftForPhotos();
  // Keyframes larger than this are downscaled first (MappingOptions::photo_feature_side_px says
  // why 480) [px].
  int max_side_px = 480;

  bool Check(std::string* error) const;
};

// A keyframe's photo features: those with a 3D point only, since a photo is matched to points.
Features ExtractPhotoFeatures(const cv::Mat& color, const cv::Mat& depth,
                              const Intrinsics& intrinsics,
                              const PhotoFeatureExtraction& extraction);

// Extracts and stores the photo features of every keyframe of `model` (open for writing) that
// stores its images but no photo features, each in its own transaction: an interrupted run keeps
// what it stored and the next one goes on from there. `progress(done, total)` is called after
// each keyframe. Returns how many keyframes got features.
int64_t AddMissingPhotoFeatures(store::Model* model, const PhotoFeatureExtraction& extraction,
                                const std::function<void(int64_t, int64_t)>& progress = {});

}  // namespace sightmap::mapping
