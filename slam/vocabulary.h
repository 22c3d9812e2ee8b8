// A visual vocabulary for binary (ORB) descriptors: a tree of k-majority clusters (DBoW2's
// hierarchical k-means on Hamming space) whose leaves are the words, with tf-idf weights. It turns
// an image's descriptors into a sparse bag-of-words vector that place recognition (PlaceIndex) and
// photo localisation compare.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

namespace sightmap::slam {

// Sparse tf-idf vector: (word id, weight) sorted by word id, weights positive and summing to 1
// (empty when the image has no descriptor or only words every training image has).
using BowVector = std::vector<std::pair<int, float>>;

struct VocabularyOptions {
  // Children per tree node and tree levels below the root: up to branching^depth words.
  int branching = 10;
  int depth = 4;
  // Assign-and-update rounds of k-majority at each node (stops early when no assignment changes).
  int kmeans_iterations = 10;
  // Training descriptors beyond this many are subsampled (uniformly, by `seed`) before clustering;
  // all descriptors still count for the idf weights.
  int max_training_descriptors = 200000;
  // Seed of k-means++ seeding and subsampling: the same seed and data give the same bytes.
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const VocabularyOptions& options);
void from_json(const nlohmann::json& json, VocabularyOptions& options);

class Vocabulary {
 public:
  // The format name the model's vocabulary table stores with Serialize()'s bytes.
  static constexpr const char* kFormat = "sightmap-orb-bow-v1";

  // An empty vocabulary (no words): Transform and WordOf throw until one is trained or loaded.
  Vocabulary() = default;

  // Clusters the descriptors (one CV_8U matrix of 32-byte rows per training image) into words and
  // weights each word by its idf, log(N / n_i), over the N images that have descriptors (n_i of
  // them contain word i). Needs at least two images with descriptors. Throws InvalidArgument on
  // bad options or descriptors that are not ORB's.
  static Vocabulary Train(const std::vector<cv::Mat>& descriptors_per_image,
                          const VocabularyOptions& options = VocabularyOptions());

  int NumWords() const { return num_words_; }
  bool empty() const { return num_words_ == 0; }
  // Training images the idf weights were counted over.
  int NumTrainingImages() const { return num_training_images_; }
  // Idf weight of a word (0 for a word every training image has).
  float WordWeight(int word) const;

  // The word of one 32-byte descriptor: the leaf reached by descending to the nearest child.
  int WordOf(const uint8_t* descriptor32) const;
  // The tree node a descriptor reaches after descending `level` levels from the root (the leaf, if
  // the tree is shallower there), as an index in [0, NumNodes()): level 0 is the root. Descriptors
  // that share a node at a coarse level are candidates for the same point, which lets matching
  // compare a descriptor only with those of its own node (DBoW2's direct index, as ORB-SLAM uses).
  int NodeOf(const uint8_t* descriptor32, int level) const;
  int NumNodes() const { return static_cast<int>(nodes_.size()); }

  // The tf-idf vector of one image's descriptors (CV_8U, 32 columns, any number of rows; an
  // empty matrix gives an empty vector). `word_of_row`, when given, receives each row's word.
  BowVector Transform(const cv::Mat& descriptors, std::vector<int>* word_of_row = nullptr) const;

  // Little-endian bytes with a checksum; Deserialize throws sightmap::Error with a one-line
  // message on truncated, corrupt or other-version data.
  std::vector<uint8_t> Serialize() const;
  static Vocabulary Deserialize(const std::vector<uint8_t>& bytes);

  // DBoW2's L1 score of two BowVectors: 1 - 0.5 * |a - b|_1, in [0, 1] (1 for equal vectors, 0
  // for vectors sharing no word).
  static double Score(const BowVector& a, const BowVector& b);

 private:
  struct Node {
    uint64_t descriptor[4] = {0, 0, 0, 0};
    uint32_t first_child = 0;
    uint32_t num_children = 0;  // 0 for a leaf
    int32_t word = -1;          // leaves only
  };

  // The node `descriptor` reaches after at most `max_levels` descents (an index into nodes_).
  uint32_t Descend(const uint64_t descriptor[4], int max_levels) const;
  // Train's stages: the tree of words by hierarchical k-majority of descriptors[members] (breadth
  // first, numbering the leaves as words), then each word's idf over every training image.
  void BuildTree(const std::vector<std::array<uint64_t, 4>>& descriptors,
                 std::vector<uint32_t> members, const VocabularyOptions& options,
                 std::mt19937_64& rng);
  void ComputeIdf(const std::vector<cv::Mat>& descriptors_per_image, int images_with_descriptors);

  int branching_ = 0;
  int depth_ = 0;
  int num_words_ = 0;
  int num_training_images_ = 0;
  // Breadth-first: node 0 is the root, each node's children are contiguous and come after it.
  std::vector<Node> nodes_;
  std::vector<float> idf_;  // per word
};

}  // namespace sightmap::slam
