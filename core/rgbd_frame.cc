#include "core/rgbd_frame.h"

namespace sightmap {

double ValidDepthFraction(const cv::Mat& depth_mm) {
  if (depth_mm.empty()) return 0.0;
  return static_cast<double>(cv::countNonZero(depth_mm)) / static_cast<double>(depth_mm.total());
}

}  // namespace sightmap
