#include "slam/vocabulary.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <random>

#include <opencv2/core/check.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "slam/hamming.h"

namespace sightmap::slam {
namespace {

constexpr int kDescriptorBytes = 32;
using Descriptor = std::array<uint64_t, 4>;

inline Descriptor Load(const uint8_t* bytes) {
  Descriptor d;
  std::memcpy(d.data(), bytes, kDescriptorBytes);
  return d;
}

// Throws InvalidArgument unless `descriptors` is empty or holds ORB descriptors.
void CheckBinaryDescriptors(const cv::Mat& descriptors, const char* what) {
  if (descriptors.empty()) return;
  if (descriptors.type() != CV_8UC1 || descriptors.cols != kDescriptorBytes) {
    SIGHTMAP_THROW(InvalidArgument,
                   what << " takes binary ORB descriptors (CV_8UC1, 32 bytes a row); got "
                        << cv::typeToString(descriptors.type()) << " with " << descriptors.cols
                        << " columns");
  }
}

// Portable draws from a std::mt19937_64 (whose output the standard fixes, unlike the
// distributions'), so the same seed gives the same vocabulary bytes with any standard library.
uint64_t DrawIndex(std::mt19937_64& rng, uint64_t n) { return rng() % n; }
double DrawUnit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// k-means++ seeding: the first centre drawn uniformly, each next one with probability
// proportional to its squared distance to the nearest centre chosen so far; fewer than k when
// every descriptor equals a centre.
std::vector<Descriptor> SeedCentres(const std::vector<Descriptor>& descriptors,
                                    const std::vector<uint32_t>& members, int k,
                                    std::mt19937_64& rng) {
  const size_t n = members.size();
  std::vector<Descriptor> centres;
  std::vector<int> nearest(n, std::numeric_limits<int>::max());
  centres.push_back(descriptors[members[DrawIndex(rng, n)]]);
  while (static_cast<int>(centres.size()) < k) {
    const Descriptor& last = centres.back();
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) {
      nearest[i] = std::min(nearest[i], Hamming256(descriptors[members[i]].data(), last.data()));
      total += static_cast<double>(nearest[i]) * nearest[i];
    }
    if (total == 0.0) break;  // every descriptor equals a centre: no more distinct clusters
    const double target = DrawUnit(rng) * total;
    double sum = 0.0;
    size_t chosen = n;
    for (size_t i = 0; i < n; ++i) {
      if (nearest[i] == 0) continue;
      sum += static_cast<double>(nearest[i]) * nearest[i];
      chosen = i;
      if (sum > target) break;
    }
    centres.push_back(descriptors[members[chosen]]);
  }
  return centres;
}

// Each member's nearest centre (the first of equals) into `assignment`; whether any changed.
bool AssignToNearest(const std::vector<Descriptor>& descriptors,
                     const std::vector<uint32_t>& members, const std::vector<Descriptor>& centres,
                     std::vector<int>* assignment) {
  bool changed = false;
  for (size_t i = 0; i < members.size(); ++i) {
    const uint64_t* d = descriptors[members[i]].data();
    int best = 0;
    int best_distance = Hamming256(d, centres[0].data());
    for (size_t c = 1; c < centres.size(); ++c) {
      const int distance = Hamming256(d, centres[c].data());
      if (distance < best_distance) {
        best_distance = distance;
        best = static_cast<int>(c);
      }
    }
    if ((*assignment)[i] != best) {
      (*assignment)[i] = best;
      changed = true;
    }
  }
  return changed;
}

// Each centre becomes the bitwise majority of its members (a bit is set when more than half have
// it); an empty cluster keeps its centre.
void MajorityCentres(const std::vector<Descriptor>& descriptors,
                     const std::vector<uint32_t>& members, const std::vector<int>& assignment,
                     std::vector<Descriptor>* centres) {
  const size_t num_centres = centres->size();
  std::vector<std::array<int, 256>> counts(num_centres);
  std::vector<int> sizes(num_centres, 0);
  for (auto& c : counts) c.fill(0);
  for (size_t i = 0; i < members.size(); ++i) {
    std::array<int, 256>& count = counts[assignment[i]];
    ++sizes[assignment[i]];
    const Descriptor& d = descriptors[members[i]];
    for (int w = 0; w < 4; ++w) {
      for (uint64_t bits = d[w]; bits != 0; bits &= bits - 1) {
        ++count[w * 64 + __builtin_ctzll(bits)];
      }
    }
  }
  for (size_t c = 0; c < num_centres; ++c) {
    if (sizes[c] == 0) continue;
    Descriptor centre = {0, 0, 0, 0};
    for (int bit = 0; bit < 256; ++bit) {
      if (2 * counts[c][bit] > sizes[c]) centre[bit / 64] |= uint64_t{1} << (bit % 64);
    }
    (*centres)[c] = centre;
  }
}

// k-majority clustering of descriptors[members] into at most k clusters, k-means++ seeded.
// Returns the centres of the non-empty clusters and each cluster's members.
void KMajority(const std::vector<Descriptor>& descriptors, const std::vector<uint32_t>& members,
               int k, int iterations, std::mt19937_64& rng, std::vector<Descriptor>* centres,
               std::vector<std::vector<uint32_t>>* clusters) {
  *centres = SeedCentres(descriptors, members, k, rng);
  std::vector<int> assignment(members.size(), -1);
  // Ends on an assignment, so each member sits with its nearest centre, as WordOf descends.
  AssignToNearest(descriptors, members, *centres, &assignment);
  for (int iteration = 1; iteration < iterations; ++iteration) {
    MajorityCentres(descriptors, members, assignment, centres);
    if (!AssignToNearest(descriptors, members, *centres, &assignment)) break;
  }
  std::vector<std::vector<uint32_t>> all(centres->size());
  for (size_t i = 0; i < members.size(); ++i) all[assignment[i]].push_back(members[i]);
  std::vector<Descriptor> kept;
  clusters->clear();
  for (size_t c = 0; c < centres->size(); ++c) {
    if (all[c].empty()) continue;
    kept.push_back((*centres)[c]);
    clusters->push_back(std::move(all[c]));
  }
  *centres = std::move(kept);
}

// The indices of the descriptors to cluster: all, or a uniform subset of `keep` of them (a partial
// Fisher-Yates shuffle), in index order.
std::vector<uint32_t> TrainingSubset(size_t total, size_t keep, std::mt19937_64& rng) {
  std::vector<uint32_t> members(total);
  for (size_t i = 0; i < total; ++i) members[i] = static_cast<uint32_t>(i);
  if (total <= keep) return members;
  for (size_t i = 0; i < keep; ++i) {
    std::swap(members[i], members[i + DrawIndex(rng, total - i)]);
  }
  members.resize(keep);
  std::sort(members.begin(), members.end());
  return members;
}

// Serialisation helpers: little-endian, bounds-checked reads.
class Writer {
 public:
  void U32(uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
  void U64(uint64_t v) {
    for (int i = 0; i < 8; ++i) bytes_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
  void F32(float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    U32(bits);
  }
  void Raw(const void* data, size_t size) {
    const uint8_t* p = static_cast<const uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + size);
  }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  size_t remaining() const { return size_ - offset_; }
  void Need(size_t n) const {
    SIGHTMAP_CHECK(remaining() >= n, "vocabulary data is truncated (" << size_ << " bytes)");
  }
  uint32_t U32() {
    Need(4);
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(data_[offset_ + i]) << (8 * i);
    offset_ += 4;
    return v;
  }
  uint64_t U64() {
    Need(8);
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(data_[offset_ + i]) << (8 * i);
    offset_ += 8;
    return v;
  }
  float F32() {
    const uint32_t bits = U32();
    float v;
    std::memcpy(&v, &bits, 4);
    return v;
  }
  void Raw(void* out, size_t size) {
    Need(size);
    std::memcpy(out, data_ + offset_, size);
    offset_ += size;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t offset_ = 0;
};

// FNV-1a, 64-bit: catches flipped bytes anywhere in the data.
uint64_t Checksum(const uint8_t* data, size_t size) {
  uint64_t hash = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

constexpr size_t kNodeBytes = kDescriptorBytes + 4 + 4 + 4;  // descriptor, first child, count, word

}  // namespace

bool VocabularyOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (branching < 2) return fail("branching must be at least 2");
  if (depth < 1) return fail("depth must be at least 1");
  double words = 1.0;
  for (int i = 0; i < depth; ++i) words *= branching;
  if (words > 1e7) return fail("branching^depth must be at most 10^7 words");
  if (kmeans_iterations < 1) return fail("kmeans_iterations must be at least 1");
  if (max_training_descriptors < branching) {
    return fail("max_training_descriptors must be at least branching");
  }
  return true;
}

Vocabulary Vocabulary::Train(const std::vector<cv::Mat>& descriptors_per_image,
                             const VocabularyOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  size_t total = 0;
  int images_with_descriptors = 0;
  for (const cv::Mat& descriptors : descriptors_per_image) {
    CheckBinaryDescriptors(descriptors, "Vocabulary::Train");
    total += static_cast<size_t>(descriptors.rows);
    if (!descriptors.empty()) ++images_with_descriptors;
  }
  if (images_with_descriptors < 2) {
    SIGHTMAP_THROW(InvalidArgument, "Vocabulary::Train needs at least two images with descriptors; "
                                        << "got " << images_with_descriptors);
  }
  SIGHTMAP_CHECK(total < std::numeric_limits<uint32_t>::max(),
                 "Vocabulary::Train got too many descriptors (" << total << ")");

  std::vector<Descriptor> descriptors;
  descriptors.reserve(total);
  for (const cv::Mat& image : descriptors_per_image) {
    for (int r = 0; r < image.rows; ++r) descriptors.push_back(Load(image.ptr<uint8_t>(r)));
  }
  std::mt19937_64 rng(options.seed);
  std::vector<uint32_t> root_members =
      TrainingSubset(total, static_cast<size_t>(options.max_training_descriptors), rng);

  Vocabulary vocabulary;
  vocabulary.branching_ = options.branching;
  vocabulary.depth_ = options.depth;
  vocabulary.BuildTree(descriptors, std::move(root_members), options, rng);
  vocabulary.ComputeIdf(descriptors_per_image, images_with_descriptors);
  return vocabulary;
}

void Vocabulary::BuildTree(const std::vector<Descriptor>& descriptors,
                           std::vector<uint32_t> members, const VocabularyOptions& options,
                           std::mt19937_64& rng) {
  nodes_.clear();
  nodes_.emplace_back();  // the root; its descriptor is never compared
  struct Pending {
    uint32_t node;
    int level;
    std::vector<uint32_t> members;
  };
  std::deque<Pending> queue;
  queue.push_back({0, 0, std::move(members)});
  std::vector<Descriptor> centres;
  std::vector<std::vector<uint32_t>> clusters;
  while (!queue.empty()) {
    Pending pending = std::move(queue.front());
    queue.pop_front();
    // Too few descriptors to split into `branching` clusters, or deep enough: a leaf (word).
    if (pending.level >= options.depth ||
        pending.members.size() < static_cast<size_t>(options.branching)) {
      continue;
    }
    KMajority(descriptors, pending.members, options.branching, options.kmeans_iterations, rng,
              &centres, &clusters);
    if (clusters.size() < 2) continue;  // all descriptors alike: nothing to split
    const uint32_t first = static_cast<uint32_t>(nodes_.size());
    nodes_[pending.node].first_child = first;
    nodes_[pending.node].num_children = static_cast<uint32_t>(clusters.size());
    for (size_t c = 0; c < clusters.size(); ++c) {
      Node child;
      std::memcpy(child.descriptor, centres[c].data(), kDescriptorBytes);
      nodes_.push_back(child);
      queue.push_back(
          {first + static_cast<uint32_t>(c), pending.level + 1, std::move(clusters[c])});
    }
  }
  num_words_ = 0;
  for (Node& node : nodes_) {
    if (node.num_children == 0) node.word = num_words_++;
  }
}

void Vocabulary::ComputeIdf(const std::vector<cv::Mat>& descriptors_per_image,
                            int images_with_descriptors) {
  // Over every descriptor of every image, not only the clustered subset.
  std::vector<int> images_with_word(num_words_, 0);
  std::vector<int> last_image(num_words_, -1);
  int image_index = 0;
  for (const cv::Mat& image : descriptors_per_image) {
    for (int r = 0; r < image.rows; ++r) {
      const int word = WordOf(image.ptr<uint8_t>(r));
      if (last_image[word] != image_index) {
        last_image[word] = image_index;
        ++images_with_word[word];
      }
    }
    ++image_index;
  }
  num_training_images_ = images_with_descriptors;
  idf_.resize(num_words_);
  for (int w = 0; w < num_words_; ++w) {
    idf_[w] = static_cast<float>(
        std::log(static_cast<double>(images_with_descriptors) / std::max(images_with_word[w], 1)));
  }
}

float Vocabulary::WordWeight(int word) const {
  if (word < 0 || word >= num_words_) {
    SIGHTMAP_THROW(InvalidArgument,
                   "word " << word << " is outside the vocabulary's " << num_words_ << " words");
  }
  return idf_[word];
}

// The popcnt clone is chosen at load time (the default one serves CPUs without the instruction):
// without it each of a photo's thousands of descriptors pays a libgcc call per comparison.
__attribute__((target_clones("popcnt", "default"))) uint32_t Vocabulary::Descend(
    const uint64_t descriptor[4], int max_levels) const {
  uint32_t index = 0;
  for (int level = 0; level < max_levels && nodes_[index].num_children != 0; ++level) {
    const Node& node = nodes_[index];
    uint32_t best = node.first_child;
    int best_distance = Hamming256(descriptor, nodes_[best].descriptor);
    for (uint32_t c = 1; c < node.num_children; ++c) {
      const int distance = Hamming256(descriptor, nodes_[node.first_child + c].descriptor);
      if (distance < best_distance) {
        best_distance = distance;
        best = node.first_child + c;
      }
    }
    index = best;
  }
  return index;
}

int Vocabulary::WordOf(const uint8_t* descriptor32) const {
  SIGHTMAP_CHECK(!nodes_.empty(), "the vocabulary is empty: train or load one first");
  uint64_t d[4];
  std::memcpy(d, descriptor32, kDescriptorBytes);
  return nodes_[Descend(d, std::numeric_limits<int>::max())].word;
}

int Vocabulary::NodeOf(const uint8_t* descriptor32, int level) const {
  SIGHTMAP_CHECK(!nodes_.empty(), "the vocabulary is empty: train or load one first");
  SIGHTMAP_CHECK(level >= 0, "a tree level is not negative, got " << level);
  uint64_t d[4];
  std::memcpy(d, descriptor32, kDescriptorBytes);
  return static_cast<int>(Descend(d, level));
}

BowVector Vocabulary::Transform(const cv::Mat& descriptors, std::vector<int>* word_of_row) const {
  CheckBinaryDescriptors(descriptors, "Vocabulary::Transform");
  SIGHTMAP_CHECK(!nodes_.empty(), "the vocabulary is empty: train or load one first");
  if (word_of_row) word_of_row->assign(descriptors.rows, -1);
  std::vector<int> words(descriptors.rows);
  for (int r = 0; r < descriptors.rows; ++r) {
    words[r] = WordOf(descriptors.ptr<uint8_t>(r));
    if (word_of_row) (*word_of_row)[r] = words[r];
  }
  std::sort(words.begin(), words.end());
  BowVector bow;
  double sum = 0.0;
  for (size_t i = 0; i < words.size();) {
    size_t j = i;
    while (j < words.size() && words[j] == words[i]) ++j;
    const double weight = static_cast<double>(j - i) * idf_[words[i]];  // tf x idf
    if (weight > 0.0) {
      bow.emplace_back(words[i], static_cast<float>(weight));
      sum += weight;
    }
    i = j;
  }
  for (auto& entry : bow) entry.second = static_cast<float>(entry.second / sum);
  return bow;
}

std::vector<uint8_t> Vocabulary::Serialize() const {
  SIGHTMAP_CHECK(!nodes_.empty(), "cannot serialise an empty vocabulary");
  Writer writer;
  writer.Raw(kFormat, std::strlen(kFormat));
  writer.U32(static_cast<uint32_t>(branching_));
  writer.U32(static_cast<uint32_t>(depth_));
  writer.U32(static_cast<uint32_t>(num_training_images_));
  writer.U32(static_cast<uint32_t>(nodes_.size()));
  writer.U32(static_cast<uint32_t>(num_words_));
  for (const Node& node : nodes_) {
    for (uint64_t word : node.descriptor) writer.U64(word);
    writer.U32(node.first_child);
    writer.U32(node.num_children);
    writer.U32(static_cast<uint32_t>(node.word));
  }
  for (float idf : idf_) writer.F32(idf);
  writer.U64(Checksum(writer.bytes().data(), writer.bytes().size()));
  return std::move(writer.bytes());
}

Vocabulary Vocabulary::Deserialize(const std::vector<uint8_t>& bytes) {
  const size_t format_size = std::strlen(kFormat);
  SIGHTMAP_CHECK(
      bytes.size() >= format_size && std::memcmp(bytes.data(), kFormat, format_size) == 0,
      "vocabulary data is not in the " << kFormat << " format");
  SIGHTMAP_CHECK(bytes.size() >= format_size + 5 * 4 + 8,
                 "vocabulary data is truncated (" << bytes.size() << " bytes)");
  const size_t body = bytes.size() - 8;
  Reader trailer(bytes.data() + body, 8);
  Reader reader(bytes.data(), body);
  std::vector<char> format(format_size);
  reader.Raw(format.data(), format_size);
  Vocabulary vocabulary;
  vocabulary.branching_ = static_cast<int>(reader.U32());
  vocabulary.depth_ = static_cast<int>(reader.U32());
  vocabulary.num_training_images_ = static_cast<int>(reader.U32());
  const uint32_t num_nodes = reader.U32();
  const uint32_t num_words = reader.U32();
  // Sizes first, so neither a truncated nor a corrupt header allocates from a wrong count.
  const uint64_t expected =
      static_cast<uint64_t>(num_nodes) * kNodeBytes + static_cast<uint64_t>(num_words) * 4;
  SIGHTMAP_CHECK(expected == reader.remaining(), "vocabulary data is truncated or corrupt ("
                                                     << bytes.size() << " bytes for " << num_nodes
                                                     << " nodes)");
  SIGHTMAP_CHECK(Checksum(bytes.data(), body) == trailer.U64(),
                 "vocabulary data is corrupt (checksum mismatch)");
  // A sound checksum over wrong-but-consistent data (a bug, not noise) still must not crash
  // WordOf: check the tree's shape too.
  SIGHTMAP_CHECK(num_nodes >= 1 && num_words >= 1 && num_words <= num_nodes &&
                     vocabulary.branching_ >= 2 && vocabulary.depth_ >= 1 &&
                     vocabulary.num_training_images_ >= 0,
                 "vocabulary data is corrupt (bad header)");
  vocabulary.nodes_.resize(num_nodes);
  uint64_t next_child = 1;
  std::vector<bool> word_seen(num_words, false);
  for (uint32_t i = 0; i < num_nodes; ++i) {
    Node& node = vocabulary.nodes_[i];
    for (uint64_t& word : node.descriptor) word = reader.U64();
    node.first_child = reader.U32();
    node.num_children = reader.U32();
    node.word = static_cast<int32_t>(reader.U32());
    if (node.num_children == 0) {
      SIGHTMAP_CHECK(
          node.word >= 0 && static_cast<uint32_t>(node.word) < num_words && !word_seen[node.word],
          "vocabulary data is corrupt (bad word id at node " << i << ")");
      word_seen[node.word] = true;
    } else {
      // Breadth-first layout: children follow in order, so the tree has no cycle.
      SIGHTMAP_CHECK(node.word == -1 && node.first_child == next_child &&
                         node.num_children <= static_cast<uint32_t>(vocabulary.branching_),
                     "vocabulary data is corrupt (bad children at node " << i << ")");
      next_child += node.num_children;
    }
  }
  SIGHTMAP_CHECK(next_child == num_nodes,
                 "vocabulary data is corrupt (tree does not cover its nodes)");
  vocabulary.num_words_ = static_cast<int>(num_words);
  for (bool seen : word_seen) {
    SIGHTMAP_CHECK(seen, "vocabulary data is corrupt (missing word)");
  }
  vocabulary.idf_.resize(num_words);
  for (float& idf : vocabulary.idf_) {
    idf = reader.F32();
    SIGHTMAP_CHECK(std::isfinite(idf) && idf >= 0.0f, "vocabulary data is corrupt (bad weight)");
  }
  return vocabulary;
}

double Vocabulary::Score(const BowVector& a, const BowVector& b) {
  // With non-negative, L1-normalised weights, 1 - 0.5 |a - b|_1 = sum over shared words of
  // min(a_i, b_i).
  double score = 0.0;
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (i->first < j->first) {
      ++i;
    } else if (j->first < i->first) {
      ++j;
    } else {
      score += std::min(i->second, j->second);
      ++i;
      ++j;
    }
  }
  return std::min(score, 1.0);
}

SIGHTMAP_OPTIONS_JSON(VocabularyOptions, branching, depth, kmeans_iterations,
                      max_training_descriptors, seed)

}  // namespace sightmap::slam
