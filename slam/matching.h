// Descriptor matching with the nearest-neighbour distance ratio test (Lowe), the paper's matcher.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace sightmap {

struct MatchOptions {
  // A match is kept when its distance is below ratio x the second-nearest distance.
  double ratio = 0.8;
  // Also require the query to be the reference's nearest neighbour (cross check).
  bool mutual = true;

  bool Check(std::string* error) const;
};

// Matches query descriptors to reference descriptors (both CV_8U binary, or both CV_32F).
// DMatch::queryIdx indexes `query`, trainIdx indexes `reference`.
std::vector<cv::DMatch> MatchDescriptors(const cv::Mat& query, const cv::Mat& reference,
                                         const MatchOptions& options = MatchOptions());

}  // namespace sightmap
