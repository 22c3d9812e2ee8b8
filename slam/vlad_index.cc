#include "slam/vlad_index.h"

#include <algorithm>
#include <sstream>

#include "core/check.h"
#include "core/options_json.h"
#include "slam/features.h"

namespace sightmap::slam {
namespace {

constexpr int kRootSiftColumns = 128;

// Throws for rows that are not RootSIFT bytes; an empty matrix passes.
void CheckRootSiftRows(const cv::Mat& descriptors, const char* what) {
  if (!descriptors.empty() &&
      (descriptors.type() != CV_8U || descriptors.cols != kRootSiftColumns)) {
    SIGHTMAP_THROW(InvalidArgument, "VladIndex: " << what
                                                  << " descriptors are not RootSIFT bytes (CV_8U, "
                                                  << kRootSiftColumns << " columns)");
  }
}

// RootSIFT bytes as unit-scale floats; throws for rows of another kind.
cv::Mat ToFloatRows(const cv::Mat& descriptors, const char* what) {
  CheckRootSiftRows(descriptors, what);
  if (descriptors.empty()) return cv::Mat(0, kRootSiftColumns, CV_32F);
  cv::Mat rows;
  descriptors.convertTo(rows, CV_32F, 1.0 / kRootSiftScale);
  return rows;
}

}  // namespace

bool VladOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (centres < 1)
    why << "centres must be positive";
  else if (sample_step < 1)
    why << "sample_step must be positive";
  else if (kmeans_iterations < 1)
    why << "kmeans_iterations must be positive";
  if (why.tellp() == 0) return true;
  if (error != nullptr) *error = "VladOptions: " + why.str();
  return false;
}

SIGHTMAP_OPTIONS_JSON(VladOptions, centres, sample_step, kmeans_iterations, seed)

size_t VladIndex::SampledRows(const std::vector<cv::Mat>& descriptors, const VladOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  size_t rows = 0;
  for (const cv::Mat& image : descriptors) {
    rows += static_cast<size_t>((image.rows + options.sample_step - 1) / options.sample_step);
  }
  return rows;
}

VladIndex VladIndex::Train(const std::vector<cv::Mat>& descriptors, const VladOptions& options) {
  for (const cv::Mat& image : descriptors) CheckRootSiftRows(image, "training");
  const size_t sampled = SampledRows(descriptors, options);
  if (sampled < static_cast<size_t>(options.centres)) {
    SIGHTMAP_THROW(InvalidArgument, "VladIndex: " << sampled << " sampled descriptors for "
                                                  << options.centres << " centres");
  }
  cv::Mat sample;
  for (const cv::Mat& image : descriptors) {
    const cv::Mat rows = ToFloatRows(image, "training");
    for (int r = 0; r < rows.rows; r += options.sample_step) sample.push_back(rows.row(r));
  }
  VladIndex index;
  cv::Mat assignment;
  // k-means++ draws its seeds from this thread's OpenCV generator: seeded here for a codebook
  // that depends on the descriptors alone, and given back its state after.
  cv::RNG& rng = cv::theRNG();
  const uint64 saved_state = rng.state;
  rng.state = options.seed;
  cv::kmeans(sample, options.centres, assignment,
             cv::TermCriteria(cv::TermCriteria::COUNT, options.kmeans_iterations, 0.0), 1,
             cv::KMEANS_PP_CENTERS, index.centres_);
  rng.state = saved_state;
  cv::reduce(index.centres_.mul(index.centres_), index.centre_norms_, 1, cv::REDUCE_SUM);
  index.vectors_ = cv::Mat(0, index.dimension(), CV_32F);
  return index;
}

std::vector<int> VladIndex::Assign(const cv::Mat& rows) const {
  // |x - c|^2 = |x|^2 - 2 x.c + |c|^2, and |x|^2 is the same for every centre.
  const cv::Mat products = rows * centres_.t();
  std::vector<int> nearest(static_cast<size_t>(rows.rows), 0);
  for (int r = 0; r < rows.rows; ++r) {
    const float* product = products.ptr<float>(r);
    float best = centre_norms_.at<float>(0) - 2.0f * product[0];
    for (int c = 1; c < centres_.rows; ++c) {
      const float distance = centre_norms_.at<float>(c) - 2.0f * product[c];
      if (distance < best) {
        best = distance;
        nearest[static_cast<size_t>(r)] = c;
      }
    }
  }
  return nearest;
}

cv::Mat VladIndex::Encode(const cv::Mat& descriptors) const {
  if (empty()) SIGHTMAP_THROW(InvalidArgument, "VladIndex: Encode before Train");
  const cv::Mat rows = ToFloatRows(descriptors, "an image's");
  cv::Mat sums = cv::Mat::zeros(centres_.rows, centres_.cols, CV_32F);
  if (rows.empty()) return sums.reshape(1, 1);
  const std::vector<int> nearest = Assign(rows);
  for (int r = 0; r < rows.rows; ++r) {
    const int c = nearest[static_cast<size_t>(r)];
    sums.row(c) += rows.row(r) - centres_.row(c);
  }
  for (int c = 0; c < sums.rows; ++c) {
    const double norm = cv::norm(sums.row(c));
    if (norm > 0.0) sums.row(c) /= norm;
  }
  cv::Mat vector = sums.reshape(1, 1);
  const double norm = cv::norm(vector);
  if (norm > 0.0) vector /= norm;
  return vector;
}

void VladIndex::Add(int64_t id, const cv::Mat& descriptors) {
  if (std::find(ids_.begin(), ids_.end(), id) != ids_.end()) {
    SIGHTMAP_THROW(InvalidArgument, "VladIndex already holds image " << id);
  }
  const cv::Mat vector = Encode(descriptors);
  has_vector_.push_back(cv::norm(vector) > 0.0);
  vectors_.push_back(vector);
  ids_.push_back(id);
}

std::vector<PlaceCandidate> VladIndex::Rank(const cv::Mat& descriptors, int max_results) const {
  if (ids_.empty() || max_results <= 0) return {};
  const cv::Mat query = Encode(descriptors);
  if (cv::norm(query) == 0.0) return {};
  // One dot product a row: OpenCV's matrix product takes ~10x as long for a single column.
  std::vector<double> scores(ids_.size(), 0.0);
  std::vector<size_t> order;
  for (size_t i = 0; i < ids_.size(); ++i) {
    if (!has_vector_[i]) continue;
    scores[i] = vectors_.row(static_cast<int>(i)).dot(query);
    order.push_back(i);
  }
  const auto better = [&](size_t a, size_t b) {
    return scores[a] != scores[b] ? scores[a] > scores[b] : ids_[a] < ids_[b];
  };
  const size_t kept = std::min(order.size(), static_cast<size_t>(max_results));
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(kept), order.end(),
                    better);
  std::vector<PlaceCandidate> ranked;
  for (size_t i = 0; i < kept; ++i) {
    ranked.push_back({ids_[order[i]], scores[order[i]]});
  }
  return ranked;
}

}  // namespace sightmap::slam
