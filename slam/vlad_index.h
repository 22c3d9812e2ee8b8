// Place recognition by one global vector per image: VLAD (Jegou et al. 2010) over RootSIFT. Each
// descriptor is assigned to its nearest of k centres (k-means on the keyframes' own descriptors),
// the residuals to each centre are summed, each centre's sum is scaled to unit length
// (intra-normalisation, Arandjelovic and Zisserman 2013, so that a wall of one repeated texture
// does not outweigh the rest of the view) and the whole to unit length. Images compare by the dot
// product of their vectors.
//
// Why beside the ORB bag of words and votes: a phone photo taken farther or at another angle than
// the walk's keyframes shares few ORB words with them, while RootSIFT holds up across such changes.
// For the RootSIFT second look (identify::LocatorOptions::second_look_retrieval): on 200 session-2
// photos against the survey walk's SLAM model, of the 42 photos whose view a keyframe covered but
// that went unmatched, VLAD ranked a covering keyframe first for 7, among its first 5 for 16 and
// its first 10 for 18 (README "Retrieval for the second look").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "slam/place_index.h"

namespace sightmap::slam {

struct VladOptions {
  int centres = 64;  // k of the k-means codebook: vectors of centres x 128 floats
  // The codebook is trained on every sample_step-th descriptor of the keyframes (and at least
  // `centres` of them), in kmeans_iterations Lloyd iterations from k-means++ seeds drawn with
  // `seed`, so the same keyframes give the same codebook.
  int sample_step = 10;
  int kmeans_iterations = 15;
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const VladOptions& options);
void from_json(const nlohmann::json& json, VladOptions& options);

class VladIndex {
 public:
  VladIndex() = default;

  // Trains the codebook on RootSIFT rows (CV_8U, 128 columns, slam::kRootSiftScale per unit, as
  // the model stores them) of several images. Throws InvalidArgument for invalid options,
  // descriptors that are not RootSIFT bytes, or fewer sampled rows than centres.
  static VladIndex Train(const std::vector<cv::Mat>& descriptors, const VladOptions& options);
  // The rows Train samples from these images (every sample_step-th of each): Train needs at least
  // options.centres.
  static size_t SampledRows(const std::vector<cv::Mat>& descriptors, const VladOptions& options);

  bool empty() const { return centres_.empty(); }
  size_t size() const { return ids_.size(); }
  int dimension() const { return centres_.rows * centres_.cols; }

  // The unit vector (1 x dimension, CV_32F) of one image's RootSIFT rows; all zeros for none.
  // Throws InvalidArgument before Train or for rows that are not RootSIFT bytes.
  cv::Mat Encode(const cv::Mat& descriptors) const;

  // Adds an image's vector under `id`. Throws InvalidArgument on a duplicate id.
  void Add(int64_t id, const cv::Mat& descriptors);

  // The images most like the query, at most max_results, best first (ties by smaller id); score is
  // the dot product of the vectors, in [-1, 1]. Images without descriptors (a zero vector) are
  // left out. Thread-safe for concurrent calls on an index nobody adds to.
  std::vector<PlaceCandidate> Rank(const cv::Mat& descriptors, int max_results) const;

 private:
  // Each row's nearest centre.
  std::vector<int> Assign(const cv::Mat& rows) const;

  cv::Mat centres_;       // k x 128, CV_32F, in RootSIFT's unit-norm scale
  cv::Mat centre_norms_;  // k x 1, squared norms of the centres
  cv::Mat vectors_;       // one row per image added
  std::vector<int64_t> ids_;
  std::vector<bool> has_vector_;  // per image: it had descriptors
};

}  // namespace sightmap::slam
