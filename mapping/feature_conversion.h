// The one place where slam's Features and store's KeyframeFeatures meet: slam marks a keypoint
// without depth with has_point = false, the store keeps a NaN point instead.
#pragma once

#include "slam/features.h"
#include "store/model.h"

namespace sightmap::mapping {

// Points become float [m]; a keypoint without a point gets NaN coordinates.
KeyframeFeatures ToStoreFeatures(const Features& features);
// A keypoint whose stored point has a NaN coordinate gets has_point = false.
Features FromStoreFeatures(const KeyframeFeatures& features);

}  // namespace sightmap::mapping
