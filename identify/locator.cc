#include "identify/locator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <mutex>
#include <sstream>
#include <unordered_map>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"
#include "identify/exif.h"
#include "identify/visibility.h"
#include "slam/hamming.h"
#include "slam/place_index.h"
#include "slam/vocabulary.h"

namespace sightmap::identify {

bool LocatorOptions::Check(std::string* error) const {
  std::ostringstream why;
  if (!features.Check(error)) return false;
  if (max_image_side_px < 320)
    why << "max_image_side_px must be at least 320";
  else if (retrieval_candidates < 1)
    why << "retrieval_candidates must be at least 1";
  else if (neighbour_radius_m < 0.0 || max_neighbours < 0)
    why << "neighbour_radius_m and max_neighbours must not be negative";
  else if (match_node_level < 0)
    why << "match_node_level must not be negative";
  else if (match_node_level < 0)
    why << "match_node_level must not be negative";
  else if (!(match_ratio > 0.0 && match_ratio <= 1.0))
    why << "match_ratio must be in (0, 1]";
  else if (same_point_m < 0.0)
    why << "same_point_m must not be negative";
  else if (max_descriptor_distance < 1)
    why << "max_descriptor_distance must be positive";
  else if (!(pnp_reprojection_px > 0.0) || pnp_iterations < 1)
    why << "pnp_reprojection_px and pnp_iterations must be positive";
  else if (min_inliers < 4)
    why << "min_inliers must be at least 4 (PnP needs 4 points)";
  else if (confident_inliers < min_inliers)
    why << "confident_inliers must be at least min_inliers";
  else if (!(max_rotation_from_keyframe_deg > 0.0 && max_rotation_from_keyframe_deg <= 180.0))
    why << "max_rotation_from_keyframe_deg must be in (0, 180]";
  else if (!(place_radius_m >= 0.0) || !(place_max_angle_deg >= 0.0) || max_places < 1)
    why << "place_radius_m and place_max_angle_deg must not be negative, max_places positive";
  else if (min_ransac_inliers < 4 || !(guided_radius_px > 0.0) || guided_max_distance < 1 ||
           guided_rounds < 0)
    why << "min_ransac_inliers must be at least 4, guided_radius_px and guided_max_distance "
           "positive, guided_rounds not negative";
  else if (min_inlier_cells < 0 || min_inlier_cells > 16)
    why << "min_inlier_cells must be in [0, 16]";
  else if (bare_view_max_detail_cells < 0 || bare_view_max_detail_cells > 16)
    why << "bare_view_max_detail_cells must be in [0, 16]";
  else if (!(min_inlier_share >= 0.0 && min_inlier_share <= 1.0))
    why << "min_inlier_share must be in [0, 1]";
  else if (!(same_pose_m >= 0.0) || !(same_pose_deg >= 0.0) ||
           !(min_inlier_ratio_over_runner_up >= 1.0))
    why << "same_pose_m and same_pose_deg must not be negative, "
           "min_inlier_ratio_over_runner_up at least 1";
  else if (focal_candidates_35mm.empty())
    why << "focal_candidates_35mm must not be empty";
  else if (!(occlusion_voxel_m > 0.0) || occlusion_downscale < 1 || occlusion_pixel_step < 1 ||
           !(occlusion_max_depth_m > 0.0))
    why << "occlusion_voxel_m, occlusion_downscale, occlusion_pixel_step and "
           "occlusion_max_depth_m must be positive";
  else if (occlusion_margin_m < 0.0 || occlusion_margin_ratio < 0.0)
    why << "occlusion margins must not be negative";
  else if (!(min_in_view_share > 0.0 && min_in_view_share <= 1.0) ||
           !(min_unoccluded_share > 0.0 && min_unoccluded_share <= 1.0))
    why << "min_in_view_share and min_unoccluded_share must be in (0, 1]";
  for (double f : focal_candidates_35mm) {
    if (why.tellp() == 0 && !(f > 0.0)) why << "focal_candidates_35mm must be positive";
  }
  if (why.tellp() == 0) return true;
  if (error != nullptr) *error = "LocatorOptions: " + why.str();
  return false;
}

namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

cv::Matx33d CameraMatrix(const Intrinsics& k) {
  return {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
}

VisibilityOptions ToVisibilityOptions(const LocatorOptions& options) {
  VisibilityOptions v;
  v.zbuffer_downscale = options.occlusion_downscale;
  v.margin_m = options.occlusion_margin_m;
  v.margin_ratio = options.occlusion_margin_ratio;
  v.min_in_view_share = options.min_in_view_share;
  v.min_unoccluded_share = options.min_unoccluded_share;
  return v;
}

// What PnP found for one candidate and one set of intrinsics.
struct PoseHypothesis {
  bool valid = false;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  Intrinsics intrinsics;  // at the feature image's scale
  std::vector<int> inliers;
};

int CountInliers(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
                 const cv::Matx33d& camera, const cv::Vec3d& rvec, const cv::Vec3d& tvec,
                 double threshold_px, std::vector<int>* inliers) {
  inliers->clear();
  if (object.empty()) return 0;  // projectPoints throws on an empty input
  std::vector<cv::Point2f> projected;
  cv::projectPoints(object, rvec, tvec, camera, cv::noArray(), projected);
  cv::Matx33d rotation;
  cv::Rodrigues(rvec, rotation);
  inliers->clear();
  const double threshold_sq = threshold_px * threshold_px;
  for (size_t i = 0; i < object.size(); ++i) {
    const cv::Vec3d p = rotation * cv::Vec3d(object[i].x, object[i].y, object[i].z) + tvec;
    if (!(p[2] > 0.0)) continue;
    const cv::Point2f d = projected[i] - image[i];
    if (d.x * d.x + d.y * d.y <= threshold_sq) inliers->push_back(static_cast<int>(i));
  }
  return static_cast<int>(inliers->size());
}

template <typename T>
std::vector<T> Subset(const std::vector<T>& values, const std::vector<int>& indices) {
  std::vector<T> subset;
  subset.reserve(indices.size());
  for (int i : indices) subset.push_back(values[static_cast<size_t>(i)]);
  return subset;
}

void ToRvecTvec(const Eigen::Isometry3d& world_from_cam, cv::Vec3d* rvec, cv::Vec3d* tvec) {
  const Eigen::Isometry3d cam_from_world = world_from_cam.inverse();
  cv::Matx33d rotation;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rotation(r, c) = cam_from_world.linear()(r, c);
    (*tvec)[r] = cam_from_world.translation()[r];
  }
  cv::Rodrigues(rotation, *rvec);
}

Eigen::Isometry3d FromRvecTvec(const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  cv::Matx33d rotation;
  cv::Rodrigues(rvec, rotation);
  Eigen::Isometry3d cam_from_world = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) cam_from_world.linear()(r, c) = rotation(r, c);
    cam_from_world.translation()[r] = tvec[r];
  }
  return cam_from_world.inverse();
}

// RANSAC PnP, then Levenberg-Marquardt on the inliers and again on the inliers of the refined
// pose (RANSAC's minimal-sample poses leave a few cm that the refinement removes).
PoseHypothesis SolvePoseUnguarded(const std::vector<cv::Point3f>& object,
                                  const std::vector<cv::Point2f>& image,
                                  const Intrinsics& intrinsics, const LocatorOptions& options) {
  PoseHypothesis hypothesis;
  hypothesis.intrinsics = intrinsics;
  if (object.size() < 4) return hypothesis;
  const cv::Matx33d camera = CameraMatrix(intrinsics);
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  std::vector<int> inliers;
  const bool found = cv::solvePnPRansac(
      object, image, camera, cv::noArray(), rvec, tvec, false, options.pnp_iterations,
      static_cast<float>(options.pnp_reprojection_px), 0.999, inliers, cv::SOLVEPNP_AP3P);
  if (!found || inliers.size() < 4) return hypothesis;
  for (int round = 0; round < 2; ++round) {
    cv::solvePnPRefineLM(Subset(object, inliers), Subset(image, inliers), camera, cv::noArray(),
                         rvec, tvec);
    if (CountInliers(object, image, camera, rvec, tvec, options.pnp_reprojection_px, &inliers) <
        4) {
      return hypothesis;
    }
  }
  hypothesis.valid = true;
  hypothesis.world_from_cam = FromRvecTvec(rvec, tvec);
  hypothesis.inliers = std::move(inliers);
  return hypothesis;
}

// OpenCV's PnP throws on some degenerate inputs (collinear or repeated points); a degenerate
// sample is a failed hypothesis, not a failed request.
PoseHypothesis SolvePose(const std::vector<cv::Point3f>& object,
                         const std::vector<cv::Point2f>& image, const Intrinsics& intrinsics,
                         const LocatorOptions& options) {
  try {
    return SolvePoseUnguarded(object, image, intrinsics, options);
  } catch (const cv::Exception&) {
    PoseHypothesis failed;
    failed.intrinsics = intrinsics;
    return failed;
  }
}

// Refines the focal length with the pose on a hypothesis' inliers (principal point, aspect ratio
// and zero distortion fixed); keeps the hypothesis when that does not gain inliers.
void RefineFocal(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
                 const LocatorOptions& options, PoseHypothesis* hypothesis) {
  if (hypothesis->inliers.size() < 12) return;
  const Intrinsics& k = hypothesis->intrinsics;
  cv::Mat camera = cv::Mat(CameraMatrix(k)).clone();
  cv::Mat distortion = cv::Mat::zeros(5, 1, CV_64F);
  std::vector<std::vector<cv::Point3f>> objects = {Subset(object, hypothesis->inliers)};
  std::vector<std::vector<cv::Point2f>> images = {Subset(image, hypothesis->inliers)};
  std::vector<cv::Mat> rvecs;
  std::vector<cv::Mat> tvecs;
  const int flags = cv::CALIB_USE_INTRINSIC_GUESS | cv::CALIB_FIX_PRINCIPAL_POINT |
                    cv::CALIB_FIX_ASPECT_RATIO | cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K1 |
                    cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3;
  try {
    cv::calibrateCamera(
        objects, images, cv::Size(k.width, k.height), camera, distortion, rvecs, tvecs, flags,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-9));
  } catch (const cv::Exception&) {
    return;  // degenerate inliers: keep the candidate focal length
  }
  const double f = camera.at<double>(0, 0);
  // The candidates are ~15% apart, so the truth lies within ~8% of the best one; a refinement
  // that leaves that band has followed the focal-depth ambiguity of a shallow scene.
  if (!(std::abs(f / k.fx - 1.0) <= 0.1)) return;
  Intrinsics refined = k;
  refined.fx = refined.fy = f;
  PoseHypothesis again = SolvePose(object, image, refined, options);
  if (again.valid && again.inliers.size() >= hypothesis->inliers.size()) *hypothesis = again;
}

// The photo's keypoints bucketed into square cells, for window searches around projected points.
class PhotoGrid {
 public:
  PhotoGrid(const std::vector<cv::Point2f>& points, int width, int height, double cell_px)
      : cell_(std::max(1.0, cell_px)),
        cols_(std::max(1, static_cast<int>(std::ceil(width / cell_)))),
        rows_(std::max(1, static_cast<int>(std::ceil(height / cell_)))),
        cells_(static_cast<size_t>(cols_ * rows_)) {
    for (size_t i = 0; i < points.size(); ++i) {
      const int c = std::clamp(static_cast<int>(points[i].x / cell_), 0, cols_ - 1);
      const int r = std::clamp(static_cast<int>(points[i].y / cell_), 0, rows_ - 1);
      cells_[static_cast<size_t>(r * cols_ + c)].push_back(static_cast<int>(i));
    }
  }

  // Calls visit(index) for every keypoint in the cells a window of `radius` around p touches.
  template <typename Visit>
  void ForEachNear(const cv::Point2f& p, double radius, Visit visit) const {
    const int c0 = std::max(0, static_cast<int>((p.x - radius) / cell_));
    const int c1 = std::min(cols_ - 1, static_cast<int>((p.x + radius) / cell_));
    const int r0 = std::max(0, static_cast<int>((p.y - radius) / cell_));
    const int r1 = std::min(rows_ - 1, static_cast<int>((p.y + radius) / cell_));
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        for (int i : cells_[static_cast<size_t>(r * cols_ + c)]) visit(i);
      }
    }
  }

 private:
  double cell_;
  int cols_;
  int rows_;
  std::vector<std::vector<int>> cells_;
};

// The k nearest `train` descriptors of each `query` descriptor among those under the same
// vocabulary node, nearest first, as cv::BFMatcher::knnMatch gives them.
std::vector<std::vector<cv::DMatch>> KnnWithinNodes(const cv::Mat& query,
                                                    const std::vector<int>& query_nodes,
                                                    const cv::Mat& train,
                                                    const std::vector<int>& train_nodes, size_t k) {
  SIGHTMAP_CHECK(query_nodes.size() == static_cast<size_t>(query.rows) &&
                     train_nodes.size() == static_cast<size_t>(train.rows),
                 "one vocabulary node per descriptor");
  // Train rows sorted by node, so each query scans only its own node's run.
  std::vector<std::pair<int, int>> by_node(train_nodes.size());
  for (size_t r = 0; r < train_nodes.size(); ++r) {
    by_node[r] = {train_nodes[r], static_cast<int>(r)};
  }
  std::sort(by_node.begin(), by_node.end());
  std::vector<std::vector<cv::DMatch>> knn(static_cast<size_t>(query.rows));
  for (int q = 0; q < query.rows; ++q) {
    const int node = query_nodes[static_cast<size_t>(q)];
    auto it = std::lower_bound(by_node.begin(), by_node.end(), std::pair(node, -1));
    std::vector<cv::DMatch>& nearest = knn[static_cast<size_t>(q)];
    const uint8_t* d = query.ptr<uint8_t>(q);
    for (; it != by_node.end() && it->first == node; ++it) {
      const float distance =
          static_cast<float>(slam::Hamming256(d, train.ptr<uint8_t>(it->second)));
      if (nearest.size() == k && distance >= nearest.back().distance) continue;
      if (nearest.size() == k) nearest.pop_back();
      auto at = std::upper_bound(
          nearest.begin(), nearest.end(), distance,
          [](float value, const cv::DMatch& match) { return value < match.distance; });
      nearest.insert(at, cv::DMatch(q, it->second, distance));
    }
  }
  return knn;
}

// Each model point projected with the hypothesis' pose takes the photo keypoint within
// guided_radius_px whose descriptor is nearest (if within guided_max_distance); a photo keypoint
// claimed by several model points (the same point in several keyframes) keeps the nearest.
// `model_index` receives each correspondence's row in `model_points`.
void GuidedMatch(const cv::Mat& photo_descriptors, const std::vector<cv::Point2f>& photo_points,
                 const PhotoGrid& grid, const cv::Mat& model_descriptors,
                 const std::vector<cv::Point3f>& model_points, const PoseHypothesis& hypothesis,
                 const LocatorOptions& options, std::vector<cv::Point3f>* object,
                 std::vector<cv::Point2f>* image, std::vector<int>* model_index, int* projected) {
  *projected = 0;
  object->clear();
  image->clear();
  model_index->clear();
  if (model_points.empty()) return;
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  ToRvecTvec(hypothesis.world_from_cam, &rvec, &tvec);
  const Intrinsics& k = hypothesis.intrinsics;
  cv::Matx33d rotation;
  cv::Rodrigues(rvec, rotation);
  std::vector<int> best_model(photo_points.size(), -1);
  std::vector<int> best_distance(photo_points.size(), options.guided_max_distance + 1);
  const double radius_sq = options.guided_radius_px * options.guided_radius_px;
  for (size_t m = 0; m < model_points.size(); ++m) {
    const cv::Point3f& w = model_points[m];
    const cv::Vec3d p = rotation * cv::Vec3d(w.x, w.y, w.z) + tvec;
    if (!(p[2] > 0.1)) continue;
    const cv::Point2f uv(static_cast<float>(k.fx * p[0] / p[2] + k.cx),
                         static_cast<float>(k.fy * p[1] / p[2] + k.cy));
    if (uv.x < 0 || uv.y < 0 || uv.x >= k.width || uv.y >= k.height) continue;
    ++*projected;
    const uint8_t* model_row = model_descriptors.ptr<uint8_t>(static_cast<int>(m));
    int nearest = -1;
    int nearest_distance = options.guided_max_distance + 1;
    grid.ForEachNear(uv, options.guided_radius_px, [&](int i) {
      const cv::Point2f d = photo_points[static_cast<size_t>(i)] - uv;
      if (d.x * d.x + d.y * d.y > radius_sq) return;
      const int distance = slam::Hamming256(photo_descriptors.ptr<uint8_t>(i), model_row);
      if (distance < nearest_distance) {
        nearest_distance = distance;
        nearest = i;
      }
    });
    if (nearest < 0 || nearest_distance >= best_distance[static_cast<size_t>(nearest)]) continue;
    best_distance[static_cast<size_t>(nearest)] = nearest_distance;
    best_model[static_cast<size_t>(nearest)] = static_cast<int>(m);
  }
  for (size_t i = 0; i < photo_points.size(); ++i) {
    if (best_model[i] < 0) continue;
    object->push_back(model_points[static_cast<size_t>(best_model[i])]);
    image->push_back(photo_points[i]);
    model_index->push_back(best_model[i]);
  }
}

// Levenberg-Marquardt from the hypothesis' pose on the correspondences within the reprojection
// threshold, twice; false (hypothesis invalid) when fewer than 4 remain.
bool RefineOn(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
              const LocatorOptions& options, PoseHypothesis* hypothesis) {
  const cv::Matx33d camera = CameraMatrix(hypothesis->intrinsics);
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  ToRvecTvec(hypothesis->world_from_cam, &rvec, &tvec);
  std::vector<int> inliers;
  for (int round = 0; round < 2; ++round) {
    if (CountInliers(object, image, camera, rvec, tvec, options.pnp_reprojection_px, &inliers) <
        4) {
      hypothesis->valid = false;
      return false;
    }
    try {
      cv::solvePnPRefineLM(Subset(object, inliers), Subset(image, inliers), camera, cv::noArray(),
                           rvec, tvec);
    } catch (const cv::Exception&) {
      hypothesis->valid = false;  // degenerate correspondences, as in SolvePose
      return false;
    }
  }
  CountInliers(object, image, camera, rvec, tvec, options.pnp_reprojection_px, &inliers);
  hypothesis->world_from_cam = FromRvecTvec(rvec, tvec);
  hypothesis->inliers = std::move(inliers);
  hypothesis->valid = hypothesis->inliers.size() >= 4;
  return hypothesis->valid;
}

// Cells of a 4x4 grid over a width x height photo holding at least `min_points` of the points
// point_at(0 .. count-1).
template <typename PointAt>
int GridCellsHolding(size_t count, PointAt point_at, int width, int height, int min_points) {
  constexpr int kCells = 4;
  int counts[kCells * kCells] = {};
  for (size_t i = 0; i < count; ++i) {
    const cv::Point2f p = point_at(i);
    const int c = std::clamp(static_cast<int>(p.x * kCells / width), 0, kCells - 1);
    const int r = std::clamp(static_cast<int>(p.y * kCells / height), 0, kCells - 1);
    ++counts[r * kCells + c];
  }
  return static_cast<int>(std::count_if(std::begin(counts), std::end(counts),
                                        [min_points](int n) { return n >= min_points; }));
}

// Cells holding at least one inlier: inliers bunched in one corner (a poster, a repeated pattern)
// do not pin a pose down.
int CoveredCells(const std::vector<cv::Point2f>& image, const std::vector<int>& inliers, int width,
                 int height) {
  return GridCellsHolding(
      inliers.size(), [&](size_t i) { return image[static_cast<size_t>(inliers[i])]; }, width,
      height, 1);
}

// A cell holds detail with this many features (of up to 3,000 over 16 cells).
constexpr int kDetailCellFeatures = 20;

// Cells holding detail: a photo of a bare ceiling or wall has its few features in one or two.
int DetailCells(const Features& features, const cv::Size& size) {
  return GridCellsHolding(
      features.keypoints.size(), [&](size_t i) { return features.keypoints[i].pt; }, size.width,
      size.height, kDetailCellFeatures);
}

}  // namespace

struct Locator::Impl {
  struct ModelKeyframe {
    KeyframeId id;
    Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
    Eigen::Vector3d view_direction = Eigen::Vector3d::UnitZ();  // camera z in the world
    // The features that have a 3D point: their descriptors (one row each) and world points [m].
    cv::Mat descriptors;
    std::vector<cv::Point3f> world_points;
    std::vector<int> nodes;  // per descriptor: its vocabulary node at match_node_level (> 0 only)
    std::vector<size_t> neighbours;  // slots, nearest first
  };
  // Retrieved keyframes of one part of the building: the best-scoring one (head) and the slots
  // matched together (candidates and their neighbours).
  struct Place {
    size_t head = 0;
    std::vector<size_t> slots;
  };

  LocatorOptions options;
  std::vector<ModelKeyframe> keyframes;
  slam::Vocabulary vocabulary;
  slam::PlaceIndex index;  // ids are slots into `keyframes`
  OcclusionCloud cloud;
  // Every keyframe's depth at 80x60, to tell from which side the walk saw each label point.
  std::vector<SightingView> sighting_views;
  struct LabelSet {
    std::vector<store::LabelRecord> labels;
    LabelSightings sightings;  // per label, per point
  };
  mutable std::mutex labels_mutex;
  std::shared_ptr<const LabelSet> labels;

  std::shared_ptr<const LabelSet> CurrentLabels() const {
    std::lock_guard<std::mutex> lock(labels_mutex);
    return labels;
  }

  void FindNeighbours();
  // Retrieval candidates for a photo's descriptors, best first: the inverted index's, and in a
  // model of no more keyframes than retrieval_candidates, or without a vocabulary, every keyframe
  // (a few keyframes are cheaper to verify than to rank, and a vocabulary trained on them ranks
  // poorly).
  std::vector<slam::PlaceCandidate> Retrieve(const cv::Mat& descriptors) const;
};

std::vector<slam::PlaceCandidate> Locator::Impl::Retrieve(const cv::Mat& descriptors) const {
  std::vector<slam::PlaceCandidate> candidates;
  if (!vocabulary.empty()) {
    candidates = index.Query(vocabulary.Transform(descriptors), options.retrieval_candidates);
  }
  // Without a vocabulary (a model with one keyframe of features) there is nothing to rank by.
  if (vocabulary.empty() || keyframes.size() <= static_cast<size_t>(options.retrieval_candidates)) {
    for (size_t slot = 0; slot < keyframes.size(); ++slot) {
      const bool listed = std::any_of(
          candidates.begin(), candidates.end(),
          [&](const slam::PlaceCandidate& c) { return c.id == static_cast<int64_t>(slot); });
      if (!listed && !keyframes[slot].world_points.empty()) {
        candidates.push_back(slam::PlaceCandidate{static_cast<int64_t>(slot), 0.0});
      }
    }
  }
  return candidates;
}

void Locator::Impl::FindNeighbours() {
  // Quadratic once at load (3,000 keyframes: 9M cheap tests); retrieval itself never scans.
  const double cos_max = std::cos(options.neighbour_max_angle_deg * M_PI / 180.0);
  const double radius_sq = options.neighbour_radius_m * options.neighbour_radius_m;
  for (size_t i = 0; i < keyframes.size(); ++i) {
    std::vector<std::pair<double, size_t>> near;
    const Eigen::Vector3d p = keyframes[i].world_from_cam.translation();
    for (size_t j = 0; j < keyframes.size(); ++j) {
      if (j == i || keyframes[j].world_points.empty()) continue;
      const double d_sq = (keyframes[j].world_from_cam.translation() - p).squaredNorm();
      if (d_sq > radius_sq) continue;
      if (keyframes[j].view_direction.dot(keyframes[i].view_direction) < cos_max) continue;
      near.emplace_back(d_sq, j);
    }
    std::sort(near.begin(), near.end());
    if (near.size() > static_cast<size_t>(options.max_neighbours))
      near.resize(static_cast<size_t>(options.max_neighbours));
    for (const auto& [d_sq, j] : near) keyframes[i].neighbours.push_back(j);
  }
}

namespace {

// Descriptors the vocabulary and the matcher take: 32-byte binary (ORB) rows, at least one.
bool IsOrbDescriptors(const cv::Mat& descriptors) {
  return descriptors.rows > 0 && descriptors.type() == CV_8U && descriptors.cols == 32;
}

// The model's vocabulary; a model of fewer keyframes than the mapper trains its vocabulary on
// (a short recording) has none, and gets one trained here from its keyframes (empty when fewer
// than two have features: retrieval then tries every keyframe).
slam::Vocabulary LoadOrTrainVocabulary(const store::Model& model,
                                       const std::vector<store::KeyframeInfo>& infos) {
  const auto stored = model.LoadVocabulary();
  if (stored) {
    SIGHTMAP_CHECK(stored->first == slam::Vocabulary::kFormat,
                   "the model's vocabulary is in format '"
                       << stored->first << "', this sightmap reads '" << slam::Vocabulary::kFormat
                       << "'");
    return slam::Vocabulary::Deserialize(stored->second);
  }
  std::vector<cv::Mat> descriptors;
  for (const store::KeyframeInfo& info : infos) {
    const Features features = model.LoadFeatures(info.id);
    if (IsOrbDescriptors(features.descriptors)) descriptors.push_back(features.descriptors);
  }
  if (descriptors.size() < 2) return slam::Vocabulary();
  return slam::Vocabulary::Train(descriptors);
}

}  // namespace

Locator::Locator(const store::Model& model, const LocatorOptions& options)
    : impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK_OPTIONS(options);
  impl_->options = options;
  const std::vector<store::KeyframeInfo> infos = model.Keyframes();
  SIGHTMAP_CHECK(!infos.empty(), "the model " << model.path()
                                              << " has no keyframes: map a building into it "
                                                 "first ('sightmap map')");
  impl_->vocabulary = LoadOrTrainVocabulary(model, infos);

  OcclusionCloudBuilder cloud(options.occlusion_voxel_m);
  bool any_orb_features = false;
  impl_->keyframes.reserve(infos.size());
  for (const store::KeyframeInfo& info : infos) {
    Impl::ModelKeyframe keyframe;
    keyframe.id = info.id;
    keyframe.world_from_cam = info.world_from_cam;
    keyframe.view_direction = info.world_from_cam.linear().col(2);
    const Features features = model.LoadFeatures(info.id);
    const size_t slot = impl_->keyframes.size();
    // Every descriptor votes in retrieval; only those with a 3D point can be matched for PnP.
    if (IsOrbDescriptors(features.descriptors)) {
      // Not the index: a model with one keyframe of features has no vocabulary to index by.
      any_orb_features = true;
      if (!impl_->vocabulary.empty()) {
        impl_->index.Add(static_cast<int64_t>(slot),
                         impl_->vocabulary.Transform(features.descriptors));
      }
      std::vector<int> rows;
      for (size_t i = 0; i < features.points_cam.size(); ++i) {
        if (!features.has_point[i]) continue;
        rows.push_back(static_cast<int>(i));
        const Eigen::Vector3d world = info.world_from_cam * features.points_cam[i];
        keyframe.world_points.emplace_back(static_cast<float>(world.x()),
                                           static_cast<float>(world.y()),
                                           static_cast<float>(world.z()));
      }
      keyframe.descriptors.create(static_cast<int>(rows.size()), 32, CV_8U);
      for (size_t r = 0; r < rows.size(); ++r) {
        features.descriptors.row(rows[r]).copyTo(keyframe.descriptors.row(static_cast<int>(r)));
        if (options.match_node_level > 0 && !impl_->vocabulary.empty()) {
          keyframe.nodes.push_back(impl_->vocabulary.NodeOf(
              keyframe.descriptors.ptr<uint8_t>(static_cast<int>(r)), options.match_node_level));
        }
      }
    }
    if (info.depth_bytes > 0) {
      const cv::Mat depth = model.LoadDepth(info.id);
      cloud.AddDepth(depth, info.intrinsics, info.world_from_cam, options.occlusion_pixel_step,
                     options.features.min_depth_m, options.occlusion_max_depth_m);
      impl_->sighting_views.push_back(
          MakeSightingView(depth, info.intrinsics, info.world_from_cam, 80, 60));
    }
    impl_->keyframes.push_back(std::move(keyframe));
  }
  SIGHTMAP_CHECK(any_orb_features, "the model " << model.path()
                                                << " has no keyframe with ORB features; "
                                                   "map it again with ORB features");
  impl_->FindNeighbours();
  impl_->cloud = cloud.Build();
  ReloadLabels(model);
}

Locator::~Locator() = default;

void Locator::ReloadLabels(const store::Model& model) {
  auto labels = std::make_shared<Impl::LabelSet>();
  labels->labels = model.Labels();
  labels->sightings =
      SightLabels(labels->labels, impl_->sighting_views, ToVisibilityOptions(impl_->options));
  std::lock_guard<std::mutex> lock(impl_->labels_mutex);
  impl_->labels = std::move(labels);
}

size_t Locator::NumKeyframes() const { return impl_->keyframes.size(); }
const LocatorOptions& Locator::options() const { return impl_->options; }
size_t Locator::NumOcclusionVoxels() const { return impl_->cloud.world_points.size(); }
std::vector<store::LabelRecord> Locator::Labels() const { return impl_->CurrentLabels()->labels; }

LocateResult Locator::Locate(const cv::Mat& photo, const std::optional<Intrinsics>& intrinsics,
                             IntrinsicsSource source) const {
  const Clock::time_point start = Clock::now();
  const LocatorOptions& options = impl_->options;
  LocateResult result;
  result.intrinsics_source = intrinsics ? source : IntrinsicsSource::kEstimated;
  auto finish = [&](UnmatchedReason code, std::string reason) {
    // Matching failed on a photo whose detail is in one corner: what to do about it is to include
    // more of the room, whatever the matcher's own reason was. An ambiguous photo keeps its
    // answer (two places fit).
    const bool matching_failed =
        code == UnmatchedReason::kUnknownPlace || code == UnmatchedReason::kUnseenView ||
        code == UnmatchedReason::kFewMatches || code == UnmatchedReason::kMatchesInOneCorner;
    if (matching_failed && result.photo_detail_cells <= options.bare_view_max_detail_cells) {
      reason = "the photo shows little detail (its features fill " +
               std::to_string(result.photo_detail_cells) + " of 16 parts of it); " + reason;
      code = UnmatchedReason::kBareView;
    }
    result.matched = false;
    result.reason_code = code;
    result.reason = std::move(reason);
    result.timings.total_ms = MsSince(start);
    return result;
  };
  if (photo.empty()) return finish(UnmatchedReason::kEmptyPhoto, "the photo is empty.");
  SIGHTMAP_CHECK(photo.depth() == CV_8U &&
                     (photo.channels() == 1 || photo.channels() == 3 || photo.channels() == 4),
                 "a photo must be 8-bit grey, BGR or BGRA");

  // Intrinsics at the photo's full resolution: given ones scaled when they were for another size.
  std::vector<Intrinsics> full_candidates;
  if (intrinsics) {
    Intrinsics k = *intrinsics;
    if (k.width <= 0 || k.height <= 0) {
      k.width = photo.cols;
      k.height = photo.rows;
    }
    std::string error;
    SIGHTMAP_CHECK(k.Check(&error), "the photo's intrinsics are not usable: " << error);
    if (k.width != photo.cols || k.height != photo.rows) k = k.Scaled(photo.cols, photo.rows);
    full_candidates.push_back(k);
  } else {
    for (double f35 : options.focal_candidates_35mm) {
      full_candidates.push_back(IntrinsicsFromFocal35mm(photo.cols, photo.rows, f35));
    }
  }
  result.intrinsics = full_candidates.front();

  // Features, on a downscaled copy when the photo is larger than keyframes can match.
  Clock::time_point stage = Clock::now();
  cv::Mat grey;
  if (photo.channels() == 3)
    cv::cvtColor(photo, grey, cv::COLOR_BGR2GRAY);
  else if (photo.channels() == 4)
    cv::cvtColor(photo, grey, cv::COLOR_BGRA2GRAY);
  else
    grey = photo;
  const int longer = std::max(photo.cols, photo.rows);
  double scale = 1.0;
  if (longer > options.max_image_side_px) {
    scale = static_cast<double>(options.max_image_side_px) / longer;
    cv::resize(grey, grey,
               cv::Size(std::max(1, static_cast<int>(std::lround(photo.cols * scale))),
                        std::max(1, static_cast<int>(std::lround(photo.rows * scale)))),
               0.0, 0.0, cv::INTER_AREA);
  }
  // The photo rule refuses a side under kMinPhotoSidePx, but a caller may hand pixels directly,
  // and downscaling a long thin photo shrinks its short side: ORB's pyramid throws on a side it
  // shrinks to nothing, and finds nothing on one this short.
  if (std::min(grey.cols, grey.rows) < kMinPhotoSidePx) {
    std::ostringstream why;
    why << "the photo is too small or too narrow to hold features (" << grey.cols << "x"
        << grey.rows << " px as matched, at least " << kMinPhotoSidePx << " px a side needed).";
    return finish(UnmatchedReason::kFewFeatures, why.str());
  }
  const Features features = slam::ExtractFeatures(
      grey, cv::Mat(), full_candidates.front().Scaled(grey.cols, grey.rows), options.features);
  result.photo_features = static_cast<int>(features.size());
  result.photo_detail_cells = DetailCells(features, grey.size());
  result.timings.features_ms = MsSince(stage);
  if (static_cast<int>(features.size()) < options.min_inliers) {
    std::ostringstream why;
    why << "the photo has only " << features.size() << " features (at least " << options.min_inliers
        << " needed): it is blank, blurred or too dark.";
    return finish(UnmatchedReason::kFewFeatures, why.str());
  }

  // Retrieval through the inverted index.
  stage = Clock::now();
  const std::vector<slam::PlaceCandidate> candidates = impl_->Retrieve(features.descriptors);
  result.timings.retrieval_ms = MsSince(stage);
  if (candidates.empty()) {
    return finish(UnmatchedReason::kUnknownPlace,
                  "no keyframe of the model shares a visual word with the photo.");
  }

  std::vector<cv::Point2f> photo_points(features.size());
  for (size_t i = 0; i < features.size(); ++i) photo_points[i] = features.keypoints[i].pt;
  std::vector<Intrinsics> feature_candidates;
  for (const Intrinsics& k : full_candidates) {
    feature_candidates.push_back(k.Scaled(grey.cols, grey.rows));
  }

  // Candidates grouped into places: a candidate near an earlier one (same part of the building,
  // similar view) joins its place, so each place is matched once against the union of its
  // keyframes' and their neighbours' 3D features rather than keyframe by keyframe.
  const double place_cos = std::cos(options.place_max_angle_deg * M_PI / 180.0);
  std::vector<Impl::Place> places;
  for (const slam::PlaceCandidate& candidate : candidates) {
    const size_t slot = static_cast<size_t>(candidate.id);
    const Impl::ModelKeyframe& keyframe = impl_->keyframes[slot];
    Impl::Place* joined = nullptr;
    for (Impl::Place& place : places) {
      const Impl::ModelKeyframe& head = impl_->keyframes[place.head];
      if ((head.world_from_cam.translation() - keyframe.world_from_cam.translation()).norm() <=
              options.place_radius_m &&
          head.view_direction.dot(keyframe.view_direction) >= place_cos) {
        joined = &place;
        break;
      }
    }
    if (joined == nullptr) {
      if (static_cast<int>(places.size()) >= options.max_places) continue;
      places.push_back(Impl::Place{slot, {}});
      joined = &places.back();
    }
    auto add = [&](size_t s) {
      if (std::find(joined->slots.begin(), joined->slots.end(), s) == joined->slots.end()) {
        joined->slots.push_back(s);
      }
    };
    add(slot);
    for (size_t n : keyframe.neighbours) add(n);
  }

  const PhotoGrid grid(photo_points, grey.cols, grey.rows, options.guided_radius_px);
  PoseHypothesis best;
  size_t best_slot = 0;
  int best_matches = 0;
  int runner_up_inliers = 0;  // best of the places whose pose disagrees with the winner's
  Eigen::Isometry3d runner_up_pose = Eigen::Isometry3d::Identity();
  int most_inliers_rejected = 0;  // for the reason, when nothing verifies
  double rejected_rotation_deg = 0.0;
  int rejected_cells = -1;
  // Poses with min_inliers that a check refused: inliers and pose.
  std::vector<std::pair<int, Eigen::Isometry3d>> refused;
  // Vocabulary nodes only for matching bounded by them; exhaustive matching needs none.
  const bool bounded = options.match_node_level > 0 && !impl_->vocabulary.empty();
  stage = Clock::now();
  std::vector<int> photo_nodes;
  for (int r = 0; bounded && r < features.descriptors.rows; ++r) {
    photo_nodes.push_back(
        impl_->vocabulary.NodeOf(features.descriptors.ptr<uint8_t>(r), options.match_node_level));
  }
  result.timings.matching_ms += MsSince(stage);
  const double same_point_sq = options.same_point_m * options.same_point_m;
  auto disagree = [&](const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return (a.translation() - b.translation()).norm() > options.same_pose_m ||
           RotationAngleDeg(a.linear(), b.linear()) > options.same_pose_deg;
  };
  for (const Impl::Place& place : places) {
    ++result.candidates_tried;

    // 2D-3D matches against the union of the place's keyframes.
    stage = Clock::now();
    std::vector<cv::Mat> blocks;
    std::vector<cv::Point3f> model_points;
    std::vector<int> model_nodes;
    std::vector<size_t> model_slots;  // the keyframe each model point comes from
    for (size_t s : place.slots) {
      const Impl::ModelKeyframe& member = impl_->keyframes[s];
      if (member.world_points.empty()) continue;
      blocks.push_back(member.descriptors);
      model_points.insert(model_points.end(), member.world_points.begin(),
                          member.world_points.end());
      if (bounded) model_nodes.insert(model_nodes.end(), member.nodes.begin(), member.nodes.end());
      model_slots.insert(model_slots.end(), member.world_points.size(), s);
    }
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    std::vector<int> object_model;  // per correspondence, its row in model_points
    cv::Mat model_descriptors;
    if (model_points.size() >= 2) {
      cv::vconcat(blocks, model_descriptors);
      std::vector<std::vector<cv::DMatch>> knn;
      if (bounded) {
        knn = KnnWithinNodes(features.descriptors, photo_nodes, model_descriptors, model_nodes, 4);
      } else {
        // OpenCV's exhaustive search uses the machine's vector popcount.
        cv::BFMatcher(cv::NORM_HAMMING).knnMatch(features.descriptors, model_descriptors, knn, 4);
      }
      for (const std::vector<cv::DMatch>& neighbours : knn) {
        if (neighbours.empty()) continue;
        const cv::DMatch& nearest = neighbours[0];
        if (nearest.distance > options.max_descriptor_distance) continue;
        const cv::Point3f& p = model_points[static_cast<size_t>(nearest.trainIdx)];
        // The second-nearest that is another 3D point; the same point seen by a neighbour
        // keyframe confirms rather than competes.
        bool distinct = true;
        for (size_t n = 1; n < neighbours.size(); ++n) {
          const cv::Point3f d = model_points[static_cast<size_t>(neighbours[n].trainIdx)] - p;
          if (d.dot(d) <= same_point_sq) continue;
          distinct = nearest.distance < options.match_ratio * neighbours[n].distance;
          break;
        }
        if (!distinct) continue;
        object.push_back(p);
        image.push_back(photo_points[static_cast<size_t>(nearest.queryIdx)]);
        object_model.push_back(nearest.trainIdx);
      }
    }
    result.timings.matching_ms += MsSince(stage);

    stage = Clock::now();
    PoseHypothesis found;
    for (const Intrinsics& k : feature_candidates) {
      PoseHypothesis hypothesis = SolvePose(object, image, k, options);
      // Each candidate refined before they are compared: on a shallow scene a wrong focal length
      // fits nearly as many inliers as the right one until both are refined.
      if (hypothesis.valid && !intrinsics && options.refine_estimated_focal) {
        RefineFocal(object, image, options, &hypothesis);
      }
      if (hypothesis.valid && (!found.valid || hypothesis.inliers.size() > found.inliers.size())) {
        found = std::move(hypothesis);
      }
    }
    int matches = static_cast<int>(object.size());
    int projected = 0;
    // Guided matching: the place's points projected with the first pose find their photo
    // keypoints in a small window, then the pose is refined on all of them. A right pose gains
    // many inliers; a pose fitted to chance matches (a similar room) finds few.
    if (found.valid && static_cast<int>(found.inliers.size()) >= options.min_ransac_inliers) {
      std::vector<cv::Point3f> guided_object;
      std::vector<cv::Point2f> guided_image;
      std::vector<int> guided_model;
      for (int round = 0; round < options.guided_rounds; ++round) {
        GuidedMatch(features.descriptors, photo_points, grid, model_descriptors, model_points,
                    found, options, &guided_object, &guided_image, &guided_model, &projected);
        if (!RefineOn(guided_object, guided_image, options, &found)) break;
        matches = static_cast<int>(guided_object.size());
      }
      if (found.valid) {
        object = std::move(guided_object);
        image = std::move(guided_image);
        object_model = std::move(guided_model);
      }
    }
    result.timings.pnp_ms += MsSince(stage);
    if (!found.valid) continue;
    const int inliers = static_cast<int>(found.inliers.size());
    // The paper's check is against the retrieved keyframe the pose was verified on: the member
    // of the place holding most inliers (a place spans views up to ~100 deg apart, so its head
    // may face away from a right pose).
    std::unordered_map<size_t, int> inliers_of_slot;
    for (int i : found.inliers) {
      ++inliers_of_slot[model_slots[static_cast<size_t>(object_model[static_cast<size_t>(i)])]];
    }
    size_t verified_slot = place.head;
    int verified_inliers = -1;
    for (const auto& [slot, count] : inliers_of_slot) {
      if (count > verified_inliers || (count == verified_inliers && slot < verified_slot)) {
        verified_slot = slot;
        verified_inliers = count;
      }
    }
    const double rotation_deg = RotationAngleDeg(
        impl_->keyframes[verified_slot].world_from_cam.linear(), found.world_from_cam.linear());
    const int cells = CoveredCells(image, found.inliers, grey.cols, grey.rows);
    // With the right pose a good share of the place's points that land in the photo find their
    // keypoint; a pose fitted to a texture that repeats elsewhere finds few beyond it.
    const bool low_share =
        projected > 0 && inliers < options.min_inlier_share * static_cast<double>(projected);
    if (inliers < options.min_inliers || rotation_deg > options.max_rotation_from_keyframe_deg ||
        cells < options.min_inlier_cells || low_share) {
      if (inliers >= options.min_inliers) refused.emplace_back(inliers, found.world_from_cam);
      if (inliers > most_inliers_rejected) {
        most_inliers_rejected = inliers;
        rejected_rotation_deg =
            inliers >= options.min_inliers && rotation_deg > options.max_rotation_from_keyframe_deg
                ? rotation_deg
                : 0.0;
        rejected_cells = cells;
      }
      continue;
    }
    if (!best.valid || found.inliers.size() > best.inliers.size()) {
      if (best.valid && disagree(best.world_from_cam, found.world_from_cam) &&
          static_cast<int>(best.inliers.size()) > runner_up_inliers) {
        runner_up_inliers = static_cast<int>(best.inliers.size());
        runner_up_pose = best.world_from_cam;
      }
      best = std::move(found);
      best_slot = verified_slot;
      best_matches = matches;
      result.projected_points = projected;
      result.inlier_cells = cells;
    } else if (disagree(best.world_from_cam, found.world_from_cam) && inliers > runner_up_inliers) {
      runner_up_inliers = inliers;
      runner_up_pose = found.world_from_cam;
    }
    if (static_cast<int>(best.inliers.size()) >= options.confident_inliers) break;
  }
  // A pose the checks refused still fits the photo: when it has the inliers and disagrees with
  // the winner, the view is as ambiguous as with an accepted one (measured on 200 photos: one
  // wrong pose fewer, the same right ones).
  if (best.valid) {
    for (const auto& [inliers, pose] : refused) {
      if (inliers > runner_up_inliers && disagree(best.world_from_cam, pose)) {
        runner_up_inliers = inliers;
        runner_up_pose = pose;
      }
    }
  }
  result.runner_up_inliers = runner_up_inliers;
  if (best.valid && runner_up_inliers > 0 &&
      static_cast<double>(best.inliers.size()) <
          options.min_inlier_ratio_over_runner_up * runner_up_inliers) {
    std::ostringstream why;
    why << "two places fit the photo about as well (" << best.inliers.size() << " and "
        << runner_up_inliers << " inliers, " << std::fixed << std::setprecision(1)
        << (best.world_from_cam.translation() - runner_up_pose.translation()).norm()
        << " m apart): the view is ambiguous.";
    return finish(UnmatchedReason::kAmbiguous, why.str());
  }

  if (!best.valid) {
    std::ostringstream why;
    UnmatchedReason code = UnmatchedReason::kFewMatches;
    if (rejected_rotation_deg > 0.0) {
      code = UnmatchedReason::kUnseenView;
      why << "the best pose (" << most_inliers_rejected << " inliers) turns "
          << std::lround(rejected_rotation_deg) << " deg from its keyframe (at most "
          << options.max_rotation_from_keyframe_deg << " allowed).";
    } else {
      why << "none of " << result.candidates_tried
          << " retrieved places gave a pose: " << most_inliers_rejected << " PnP inliers at best";
      if (rejected_cells >= 0 && most_inliers_rejected >= options.min_inliers) {
        code = UnmatchedReason::kMatchesInOneCorner;
        why << " but in " << rejected_cells << " cells of the photo (" << options.min_inlier_cells
            << " needed).";
      } else {
        why << ", " << options.min_inliers << " needed.";
      }
    }
    return finish(code, why.str());
  }

  result.matched = true;
  result.world_from_cam = best.world_from_cam;
  result.inliers = static_cast<int>(best.inliers.size());
  result.matches = best_matches;
  result.keyframe = impl_->keyframes[best_slot].id;
  result.intrinsics = best.intrinsics.Scaled(photo.cols, photo.rows);

  stage = Clock::now();
  const auto labels = impl_->CurrentLabels();
  result.appliances =
      AppliancesInView(labels->labels, &impl_->cloud, result.intrinsics, result.world_from_cam,
                       ToVisibilityOptions(options), &labels->sightings);
  result.timings.visibility_ms = MsSince(stage);
  result.timings.total_ms = MsSince(start);
  return result;
}

const char* ToString(UnmatchedReason reason) {
  switch (reason) {
    case UnmatchedReason::kNone:
      return "none";
    case UnmatchedReason::kEmptyPhoto:
      return "empty_photo";
    case UnmatchedReason::kFewFeatures:
      return "few_features";
    case UnmatchedReason::kUnknownPlace:
      return "unknown_place";
    case UnmatchedReason::kAmbiguous:
      return "ambiguous";
    case UnmatchedReason::kUnseenView:
      return "unseen_view";
    case UnmatchedReason::kFewMatches:
      return "few_matches";
    case UnmatchedReason::kMatchesInOneCorner:
      return "matches_in_one_corner";
    case UnmatchedReason::kBareView:
      return "bare_view";
  }
  return "unknown";
}

const char* Advice(UnmatchedReason reason) {
  switch (reason) {
    case UnmatchedReason::kNone:
      return "";
    case UnmatchedReason::kEmptyPhoto:
      return "The photo is empty: take it again.";
    case UnmatchedReason::kFewFeatures:
      return "The photo shows too little detail (blank, blurred or dark): hold the phone still, "
             "turn on the light or include more of the room.";
    case UnmatchedReason::kUnknownPlace:
      return "Nothing in the photo looks like the mapped rooms: is this a mapped floor? Step back "
             "and include more of the room.";
    case UnmatchedReason::kAmbiguous:
      return "Two places look alike in this photo: include something that tells them apart, such "
             "as a door, a window or a poster.";
    case UnmatchedReason::kUnseenView:
      return "This view of the room was not seen while mapping: take the photo from where people "
             "usually stand, or have this part of the room mapped.";
    case UnmatchedReason::kFewMatches:
      return "Too few details matched: step back or include more of the room.";
    case UnmatchedReason::kMatchesInOneCorner:
      return "Only a small part of the photo matched: step back so that more of the room is in "
             "the picture.";
    case UnmatchedReason::kBareView:
      return "Too little detail: include a wall or furniture in the photo.";
  }
  return "";
}

nlohmann::json ToJson(const LocateResult& result) {
  nlohmann::json out;
  out["matched"] = result.matched;
  if (!result.matched) {
    out["reason"] = result.reason;
    out["reason_code"] = ToString(result.reason_code);
    out["advice"] = Advice(result.reason_code);
  }
  if (result.matched) {
    const Eigen::Vector3d t = result.world_from_cam.translation();
    const Eigen::Quaterniond q(result.world_from_cam.linear());
    out["pose"] = {
        {"world_from_cam",
         {{"position", {t.x(), t.y(), t.z()}}, {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}}}};
    out["keyframe"] = result.keyframe.value();
  } else {
    out["pose"] = nullptr;
    out["keyframe"] = nullptr;
  }
  out["inliers"] = result.inliers;
  out["matches"] = result.matches;
  out["intrinsics"] = {{"fx", result.intrinsics.fx},
                       {"fy", result.intrinsics.fy},
                       {"cx", result.intrinsics.cx},
                       {"cy", result.intrinsics.cy},
                       {"width", result.intrinsics.width},
                       {"height", result.intrinsics.height},
                       {"source", ToString(result.intrinsics_source)}};
  nlohmann::json appliances = nlohmann::json::array();
  for (const ApplianceInView& appliance : result.appliances) {
    appliances.push_back({{"name", appliance.name},
                          {"type", appliance.type},
                          {"pixel", {appliance.pixel.x(), appliance.pixel.y()}},
                          {"distance_m", appliance.distance_m},
                          {"visible", !appliance.occluded},
                          {"visible_share", appliance.visible_share}});
  }
  out["appliances"] = appliances;
  out["candidates_tried"] = result.candidates_tried;
  out["photo_features"] = result.photo_features;
  out["photo_detail_cells"] = result.photo_detail_cells;
  out["timings_ms"] = {
      {"features", result.timings.features_ms},     {"retrieval", result.timings.retrieval_ms},
      {"matching", result.timings.matching_ms},     {"pnp", result.timings.pnp_ms},
      {"visibility", result.timings.visibility_ms}, {"total", result.timings.total_ms}};
  return out;
}

LocateResult Locator::Locate(const Photo& photo, const IntrinsicsHint& hint) const {
  const ChosenIntrinsics chosen = ChooseIntrinsics(photo, hint);
  LocateResult result = Locate(photo.upright, chosen.intrinsics, chosen.source);
  for (ApplianceInView& appliance : result.appliances) {
    appliance.pixel = photo.DisplayPixel(appliance.pixel);
  }
  return result;
}

SIGHTMAP_OPTIONS_JSON(LocatorOptions, features, max_image_side_px, retrieval_candidates,
                      place_radius_m, place_max_angle_deg, max_places, neighbour_radius_m,
                      neighbour_max_angle_deg, max_neighbours, match_node_level, match_ratio,
                      same_point_m, max_descriptor_distance, pnp_reprojection_px, pnp_iterations,
                      min_inliers, min_ransac_inliers, guided_radius_px, guided_max_distance,
                      guided_rounds, min_inlier_cells, bare_view_max_detail_cells, min_inlier_share,
                      same_pose_m, same_pose_deg, min_inlier_ratio_over_runner_up,
                      confident_inliers, max_rotation_from_keyframe_deg, focal_candidates_35mm,
                      refine_estimated_focal, occlusion_voxel_m, occlusion_downscale,
                      occlusion_pixel_step, occlusion_max_depth_m, occlusion_margin_m,
                      occlusion_margin_ratio, min_in_view_share, min_unoccluded_share)

}  // namespace sightmap::identify
