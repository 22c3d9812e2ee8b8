#include "slam/matching.h"

#include <opencv2/features2d.hpp>

#include "core/check.h"
#include "core/options_json.h"

namespace sightmap::slam {

bool MatchOptions::Check(std::string* error) const {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    if (error) *error = "ratio must be in (0, 1]";
    return false;
  }
  return true;
}

std::vector<cv::DMatch> MatchDescriptors(const cv::Mat& query, const cv::Mat& reference,
                                         const MatchOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  std::vector<cv::DMatch> matches;
  if (query.empty() || reference.rows < 2) return matches;
  SIGHTMAP_CHECK(query.type() == reference.type() && query.cols == reference.cols,
                 "cannot match descriptors of different types or lengths");
  const int norm = query.type() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, reference, knn, 2);

  std::vector<int> best_query_for_reference;
  if (options.mutual) {
    std::vector<cv::DMatch> backward;
    matcher.match(reference, query, backward);
    best_query_for_reference.assign(static_cast<size_t>(reference.rows), -1);
    for (const cv::DMatch& match : backward) {
      best_query_for_reference[static_cast<size_t>(match.queryIdx)] = match.trainIdx;
    }
  }
  for (const std::vector<cv::DMatch>& pair : knn) {
    if (pair.size() < 2) continue;
    if (pair[0].distance >= options.ratio * pair[1].distance) continue;
    if (options.mutual &&
        best_query_for_reference[static_cast<size_t>(pair[0].trainIdx)] != pair[0].queryIdx) {
      continue;
    }
    matches.push_back(pair[0]);
  }
  return matches;
}

SIGHTMAP_OPTIONS_JSON(MatchOptions, ratio, mutual)

}  // namespace sightmap::slam
