#include "identify/locate_stages.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "identify/exif.h"
#include "identify/photo.h"
#include "slam/features.h"
#include "slam/hamming.h"
#include "slam/matching.h"
#include "slam/pnp_ransac.h"

namespace sightmap::identify {

namespace {

cv::Matx33d CameraMatrix(const Intrinsics& k) {
  return {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
}

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

// ORB rows are 32 bytes compared by Hamming distance; RootSIFT rows 128 bytes compared by
// Euclidean distance.
bool IsBinary(const cv::Mat& descriptors) { return descriptors.cols == 32; }

std::vector<std::vector<cv::DMatch>> KNearest(const cv::Mat& query, const cv::Mat& reference,
                                              int k) {
  return IsBinary(reference) ? slam::KNearestBinary(query, reference, k)
                             : slam::KNearestEuclidean(query, reference, k);
}

// The distance of two rows of `cols` bytes: bits for ORB, rounded Euclidean for RootSIFT.
int RowDistance(const uint8_t* a, const uint8_t* b, int cols) {
  if (cols == 32) return slam::Hamming256(a, b);
  int sum = 0;
  for (int c = 0; c < cols; ++c) {
    const int d = static_cast<int>(a[c]) - static_cast<int>(b[c]);
    sum += d * d;
  }
  return static_cast<int>(std::lround(std::sqrt(static_cast<double>(sum))));
}

// The largest matching distance for descriptors like `descriptors`, in their units, and the
// largest for guided matching.
double MaxDistance(const cv::Mat& descriptors, const LocatorOptions& options) {
  return IsBinary(descriptors) ? options.max_descriptor_distance
                               : options.sift_max_distance * slam::kRootSiftScale;
}
int GuidedMaxDistance(const cv::Mat& descriptors, const LocatorOptions& options) {
  return IsBinary(descriptors) ? options.guided_max_distance
                               : static_cast<int>(std::lround(options.sift_guided_max_distance *
                                                              slam::kRootSiftScale));
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
  slam::PnpRansacOptions ransac;
  ransac.max_iterations = options.pnp_iterations;
  ransac.reprojection_px = options.pnp_reprojection_px;
  slam::PnpRansacResult found = slam::SolvePnpRansac(object, image, camera, ransac);
  if (!found.found || found.inliers.size() < 4) return hypothesis;
  cv::Vec3d rvec = found.rvec;
  cv::Vec3d tvec = found.tvec;
  std::vector<int> inliers = std::move(found.inliers);
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

// OpenCV's EPnP and refinement throw on some degenerate inputs (collinear or repeated points); a
// degenerate set of inliers is a failed hypothesis, not a failed request.
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

// The k nearest `train` descriptors of each `query` descriptor among those under the same
// vocabulary node, nearest first, as slam::KNearestBinary gives them.
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
// `radius_px` whose descriptor is nearest (if within guided_max_distance); a photo keypoint
// claimed by several model points (the same point in several keyframes) keeps the nearest.
// `model_index` receives each correspondence's row in `model_points`.
// Comparing descriptors is most of its work: the popcnt clone serves CPUs with the instruction.
__attribute__((target_clones("popcnt", "default"))) void GuidedMatch(
    const cv::Mat& photo_descriptors, const std::vector<cv::Point2f>& photo_points,
    const PhotoGrid& grid, const cv::Mat& model_descriptors,
    const std::vector<cv::Point3f>& model_points, const PoseHypothesis& hypothesis,
    int max_distance, double radius_px, std::vector<cv::Point3f>* object,
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
  std::vector<int> best_distance(photo_points.size(), max_distance + 1);
  const double radius_sq = radius_px * radius_px;
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
    int nearest_distance = max_distance + 1;
    grid.ForEachNear(uv, radius_px, [&](int i) {
      const cv::Point2f d = photo_points[static_cast<size_t>(i)] - uv;
      if (d.x * d.x + d.y * d.y > radius_sq) return;
      const int distance =
          RowDistance(photo_descriptors.ptr<uint8_t>(i), model_row, model_descriptors.cols);
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

// The cell of a cells x cells grid over a width x height image holding p, row-major.
int GridCell(const cv::Point2f& p, int width, int height, int cells) {
  const int c = std::clamp(static_cast<int>(p.x * cells / width), 0, cells - 1);
  const int r = std::clamp(static_cast<int>(p.y * cells / height), 0, cells - 1);
  return r * cells + c;
}

// Cells of a 4x4 grid over a width x height photo holding at least `min_points` of the points
// point_at(0 .. count-1).
template <typename PointAt>
int GridCellsHolding(size_t count, PointAt point_at, int width, int height, int min_points) {
  constexpr int kCells = 4;
  int counts[kCells * kCells] = {};
  for (size_t i = 0; i < count; ++i) ++counts[GridCell(point_at(i), width, height, kCells)];
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

// An 8x8 grid is fine enough that two places explaining different parts of a photo show it (a
// desk and the poster behind it).
constexpr int kFineCells = 8;

// The share of `verdict`'s inliers in fine cells where `rival` has none.
double UniqueInlierShare(const PlaceVerdict& verdict, const PlaceVerdict& rival) {
  if (verdict.inlier_fine_cells.empty()) return 1.0;
  const auto unique = std::count_if(
      verdict.inlier_fine_cells.begin(), verdict.inlier_fine_cells.end(),
      [&rival](uint8_t cell) { return (rival.fine_cell_mask & (uint64_t{1} << cell)) == 0; });
  return static_cast<double>(unique) / static_cast<double>(verdict.inlier_fine_cells.size());
}

// A cell holds detail with this many features (of up to 3,000 over 16 cells).
constexpr int kDetailCellFeatures = 20;

// Cells holding detail: a photo of a bare ceiling or wall has its few features in one or two.
// `image` (8-bit grey, BGR or BGRA) as grey, downscaled (area) when its longer side exceeds
// `max_side` [px].
cv::Mat GreyAtMostOfSide(const cv::Mat& image, int max_side) {
  cv::Mat grey;
  if (image.channels() == 3)
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  else
    grey = image;
  const cv::Size size = SizeAtMostOfSide(image.size(), max_side);
  if (size == image.size()) return grey;
  cv::Mat scaled;
  cv::resize(grey, scaled, size, 0.0, 0.0, cv::INTER_AREA);
  return scaled;
}

int DetailCells(const Features& features, const cv::Size& size) {
  return GridCellsHolding(
      features.keypoints.size(), [&](size_t i) { return features.keypoints[i].pt; }, size.width,
      size.height, kDetailCellFeatures);
}

}  // namespace

void FindNeighbours(const LocatorOptions& options, std::vector<LocatorKeyframe>* keyframes) {
  // Quadratic once at load (3,000 keyframes: 9M cheap tests); retrieval itself never scans.
  const double cos_max = std::cos(DegToRad(options.neighbour_max_angle_deg));
  const double radius_sq = options.neighbour_radius_m * options.neighbour_radius_m;
  std::vector<LocatorKeyframe>& all = *keyframes;
  for (size_t i = 0; i < all.size(); ++i) {
    std::vector<std::pair<double, size_t>> near;
    const Eigen::Vector3d p = all[i].world_from_cam.translation();
    for (size_t j = 0; j < all.size(); ++j) {
      if (j == i || all[j].world_points.empty()) continue;
      const double d_sq = (all[j].world_from_cam.translation() - p).squaredNorm();
      if (d_sq > radius_sq) continue;
      if (all[j].view_direction.dot(all[i].view_direction) < cos_max) continue;
      near.emplace_back(d_sq, j);
    }
    std::sort(near.begin(), near.end());
    if (near.size() > static_cast<size_t>(options.max_neighbours))
      near.resize(static_cast<size_t>(options.max_neighbours));
    all[i].neighbours.clear();
    for (const auto& entry : near) all[i].neighbours.push_back(entry.second);
  }
}

PhotoGrid::PhotoGrid(const std::vector<cv::Point2f>& points, int width, int height, double cell_px)
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

namespace {

// The image features are found on: its size, and the intrinsics candidates at its scale. False
// (refused) when a side is too short to hold features: the photo rule refuses a side under
// kMinPhotoSidePx, but a caller may hand pixels directly, and downscaling a long thin photo
// shrinks its short side; ORB's pyramid throws on a side it shrinks to nothing, and finds nothing
// on one this short.
bool UseFeatureImage(const cv::Mat& grey, PreparedPhoto* prepared) {
  prepared->size = grey.size();
  prepared->feature_candidates.clear();
  for (const Intrinsics& k : prepared->full_candidates) {
    prepared->feature_candidates.push_back(k.Scaled(grey.cols, grey.rows));
  }
  if (std::min(grey.cols, grey.rows) >= kMinPhotoSidePx) return true;
  std::ostringstream why;
  why << "the photo is too small or too narrow to hold features (" << grey.cols << "x" << grey.rows
      << " px as matched, at least " << kMinPhotoSidePx << " px a side needed).";
  prepared->refusal = Refusal{UnmatchedReason::kFewFeatures, why.str()};
  return false;
}

// Refuses a photo with fewer features than a pose needs inliers; else fills its keypoint
// positions and their grid.
void RefuseFewFeaturesOrIndex(const LocatorOptions& options, PreparedPhoto* prepared) {
  if (static_cast<int>(prepared->features.size()) < options.min_inliers) {
    std::ostringstream why;
    why << "the photo has only " << prepared->features.size() << " features (at least "
        << options.min_inliers << " needed): it is blank, blurred or too dark.";
    prepared->refusal = Refusal{UnmatchedReason::kFewFeatures, why.str()};
    return;
  }
  prepared->points.resize(prepared->features.size());
  for (size_t i = 0; i < prepared->features.size(); ++i) {
    prepared->points[i] = prepared->features.keypoints[i].pt;
  }
  prepared->grid = PhotoGrid(prepared->points, prepared->size.width, prepared->size.height,
                             options.guided_radius_px);
}

}  // namespace

PreparedPhoto PreparePhoto(const cv::Mat& photo, const std::optional<Intrinsics>& intrinsics,
                           const LocatorOptions& options) {
  SIGHTMAP_CHECK(!photo.empty() && photo.depth() == CV_8U &&
                     (photo.channels() == 1 || photo.channels() == 3 || photo.channels() == 4),
                 "a photo must be 8-bit grey, BGR or BGRA, and not empty");
  PreparedPhoto prepared;
  // Intrinsics at the photo's full resolution: given ones scaled when they were for another size.
  prepared.intrinsics_given = intrinsics.has_value();
  if (intrinsics) {
    Intrinsics k = *intrinsics;
    if (k.width <= 0 || k.height <= 0) {
      k.width = photo.cols;
      k.height = photo.rows;
    }
    std::string error;
    SIGHTMAP_CHECK(k.Check(&error), "the photo's intrinsics are not usable: " << error);
    if (k.width != photo.cols || k.height != photo.rows) k = k.Scaled(photo.cols, photo.rows);
    prepared.full_candidates.push_back(k);
  } else {
    for (double f35 : options.focal_candidates_35mm) {
      prepared.full_candidates.push_back(IntrinsicsFromFocal35mm(photo.cols, photo.rows, f35));
    }
  }

  // Features, on a downscaled copy when the photo is larger than keyframes can match.
  const cv::Mat grey = GreyAtMostOfSide(photo, options.max_image_side_px);
  if (!UseFeatureImage(grey, &prepared)) return prepared;
  prepared.features =
      slam::ExtractFeatures(grey, cv::Mat(), prepared.feature_candidates.front(), options.features);
  prepared.detail_cells = DetailCells(prepared.features, grey.size());
  prepared.retrieval_descriptors = prepared.features.descriptors;
  RefuseFewFeaturesOrIndex(options, &prepared);
  if (options.min_view_agreement > 0.0 && !prepared.refusal) {
    prepared.agreement_image = AgreementImage(grey, options.view_agreement);
  }
  return prepared;
}

PreparedPhoto RootSiftSeed(const PreparedPhoto& orb) {
  PreparedPhoto seed;
  seed.full_candidates = orb.full_candidates;
  seed.intrinsics_given = orb.intrinsics_given;
  seed.detail_cells = orb.detail_cells;
  seed.retrieval_descriptors = orb.retrieval_descriptors;
  seed.agreement_image = orb.agreement_image;
  return seed;
}

PreparedPhoto RootSiftPhoto(const cv::Mat& photo, const PreparedPhoto& orb,
                            const LocatorOptions& options) {
  PreparedPhoto prepared = RootSiftSeed(orb);
  const cv::Mat grey = GreyAtMostOfSide(photo, options.sift_image_side_px);
  if (!UseFeatureImage(grey, &prepared)) return prepared;
  prepared.features = slam::ExtractFeatures(grey, cv::Mat(), prepared.feature_candidates.front(),
                                            options.sift_photo_features);
  RefuseFewFeaturesOrIndex(options, &prepared);
  return prepared;
}

std::vector<slam::PlaceCandidate> RetrieveCandidates(
    const cv::Mat& descriptors, LocatorOptions::Retrieval method, int count,
    const slam::Vocabulary& vocabulary, const slam::PlaceIndex& index, const slam::VoteIndex& votes,
    const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options) {
  SIGHTMAP_CHECK(count >= 1, "RetrieveCandidates: count " << count << " must be positive");
  std::vector<slam::PlaceCandidate> candidates;
  if (!vocabulary.empty()) {
    std::vector<int> words;
    const slam::BowVector bow = vocabulary.Transform(descriptors, &words);
    if (method == LocatorOptions::Retrieval::kVotes) {
      std::vector<int64_t> shortlist;
      for (const slam::PlaceCandidate& c :
           index.Query(bow, std::max(options.vote_shortlist, count))) {
        shortlist.push_back(c.id);
      }
      candidates = votes.Rank(descriptors, words, shortlist, count);
    } else {
      candidates = index.Query(bow, count);
    }
  }
  // Without a vocabulary (a model with one keyframe of features) there is nothing to rank by.
  if (vocabulary.empty() || keyframes.size() <= static_cast<size_t>(count)) {
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

std::vector<slam::PlaceCandidate> PutKeyframesFirst(
    const std::vector<slam::PlaceCandidate>& candidates, const std::vector<KeyframeId>& first,
    const std::vector<LocatorKeyframe>& keyframes) {
  if (first.empty()) return candidates;
  std::unordered_map<int64_t, int64_t> slot_of_id;
  for (size_t slot = 0; slot < keyframes.size(); ++slot) {
    const LocatorKeyframe& keyframe = keyframes[slot];
    if (keyframe.id.valid() && !keyframe.synthetic_view.valid()) {
      slot_of_id.emplace(keyframe.id.value(), static_cast<int64_t>(slot));
    }
  }
  std::unordered_set<int64_t> first_slots;
  std::vector<slam::PlaceCandidate> unranked;
  for (const KeyframeId id : first) {
    const auto found = slot_of_id.find(id.value());
    if (found != slot_of_id.end() && first_slots.insert(found->second).second) {
      unranked.push_back(slam::PlaceCandidate{found->second, 0.0});
    }
  }
  std::vector<slam::PlaceCandidate> ranked_first;
  std::copy_if(candidates.begin(), candidates.end(), std::back_inserter(ranked_first),
               [&](const slam::PlaceCandidate& c) { return first_slots.count(c.id) > 0; });
  return MergeCandidates(MergeCandidates(ranked_first, unranked), candidates);
}

std::vector<slam::PlaceCandidate> MergeCandidates(const std::vector<slam::PlaceCandidate>& first,
                                                  const std::vector<slam::PlaceCandidate>& then) {
  std::vector<slam::PlaceCandidate> merged;
  std::unordered_set<int64_t> ids;
  for (const std::vector<slam::PlaceCandidate>* list : {&first, &then}) {
    for (const slam::PlaceCandidate& candidate : *list) {
      if (ids.insert(candidate.id).second) merged.push_back(candidate);
    }
  }
  return merged;
}

std::vector<Place> GroupPlaces(const std::vector<slam::PlaceCandidate>& candidates,
                               size_t reserve_from, int max_places,
                               const std::vector<LocatorKeyframe>& keyframes,
                               const LocatorOptions& options) {
  const double place_cos = std::cos(DegToRad(options.place_max_angle_deg));
  std::vector<Place> places;
  size_t first_places = 0;  // places candidates before reserve_from made
  for (size_t c = 0; c < candidates.size(); ++c) {
    const slam::PlaceCandidate& candidate = candidates[c];
    const size_t slot = static_cast<size_t>(candidate.id);
    SIGHTMAP_CHECK(candidate.id >= 0 && slot < keyframes.size(),
                   "retrieval candidate " << candidate.id << " is not a keyframe slot");
    const LocatorKeyframe& keyframe = keyframes[slot];
    const bool reserve = c >= reserve_from;
    if (c == reserve_from) first_places = places.size();
    Place* joined = nullptr;
    for (size_t p = 0; p < places.size(); ++p) {
      const LocatorKeyframe& head = keyframes[places[p].head];
      if ((head.world_from_cam.translation() - keyframe.world_from_cam.translation()).norm() <=
              options.place_radius_m &&
          head.view_direction.dot(keyframe.view_direction) >= place_cos) {
        joined = &places[p];
        break;
      }
    }
    // A reserve candidate seeing what a first place sees adds nothing that place lacks.
    if (reserve && joined != nullptr &&
        static_cast<size_t>(joined - places.data()) < first_places) {
      continue;
    }
    if (joined == nullptr) {
      if (static_cast<int>(places.size()) >= max_places) continue;
      places.push_back(Place{slot, {}});
      joined = &places.back();
    }
    std::vector<size_t>& slots = joined->slots;
    auto add = [&slots](size_t s) {
      if (std::find(slots.begin(), slots.end(), s) == slots.end()) slots.push_back(s);
    };
    add(slot);
    for (size_t n : keyframe.neighbours) add(n);
  }
  return places;
}

double SharedPointShare(const LocatorKeyframe& a, const LocatorKeyframe& b,
                        const LocatorOptions& options, int* matches) {
  *matches = 0;
  if (a.descriptors.empty() || b.descriptors.empty()) return 0.0;
  int shared = 0;
  const double max_distance = MaxDistance(a.descriptors, options);
  for (const std::vector<cv::DMatch>& nearest : KNearest(a.descriptors, b.descriptors, 2)) {
    if (nearest.empty() || nearest[0].distance > max_distance) continue;
    if (nearest.size() > 1 && nearest[0].distance > options.match_ratio * nearest[1].distance) {
      continue;
    }
    ++*matches;
    const cv::Point3f offset = a.world_points[static_cast<size_t>(nearest[0].queryIdx)] -
                               b.world_points[static_cast<size_t>(nearest[0].trainIdx)];
    if (std::sqrt(offset.dot(offset)) <= options.same_pose_m) ++shared;
  }
  return *matches > 0 ? static_cast<double>(shared) / *matches : 0.0;
}

std::vector<Place> TwinPlaces(const std::vector<slam::PlaceCandidate>& look_alikes,
                              size_t verified_slot, const std::vector<Place>& tried,
                              const std::vector<LocatorKeyframe>& keyframes,
                              const LocatorOptions& options) {
  SIGHTMAP_CHECK(verified_slot < keyframes.size(),
                 "verified slot " << verified_slot << " is not a keyframe slot");
  if (options.twin_places <= 0) return {};
  std::vector<slam::PlaceCandidate> twins;
  for (const slam::PlaceCandidate& candidate : look_alikes) {
    const size_t slot = static_cast<size_t>(candidate.id);
    SIGHTMAP_CHECK(candidate.id >= 0 && slot < keyframes.size(),
                   "look-alike " << candidate.id << " is not a keyframe slot");
    const bool tried_already = std::any_of(tried.begin(), tried.end(), [slot](const Place& place) {
      return std::find(place.slots.begin(), place.slots.end(), slot) != place.slots.end();
    });
    if (tried_already) continue;
    int matches = 0;
    const double shared =
        SharedPointShare(keyframes[verified_slot], keyframes[slot], options, &matches);
    if (matches >= options.twin_min_matches && shared < options.twin_max_shared_share) {
      twins.push_back(candidate);
    }
  }
  return GroupPlaces(twins, twins.size(), options.twin_places, keyframes, options);
}

namespace {

// Offset votes bucketed into cubes of twice the cluster radius: the votes within the radius of a
// point lie in the 2 x 2 x 2 cubes around the corner of its cube it is nearest to.
class OffsetGrid {
 public:
  OffsetGrid(const std::vector<Eigen::Vector3d>& offsets, double radius)
      : offsets_(offsets), radius_(radius) {
    for (size_t i = 0; i < offsets.size(); ++i) {
      cells_[KeyOf((offsets[i] / (2.0 * radius_)).array().floor())].push_back(i);
    }
  }

  // Calls visit(j) for every vote j within `radius` (at most the grid's) of `centre` whose
  // `taken` flag is false.
  template <typename Visit>
  void ForEachNear(const Eigen::Vector3d& centre, double radius, const std::vector<bool>& taken,
                   Visit visit) const {
    const Eigen::Array3d scaled = centre.array() / (2.0 * radius_);
    const Eigen::Array3d base = scaled.floor();
    Eigen::Array3d toward;  // -1 or +1 an axis: the nearer neighbour
    for (int axis = 0; axis < 3; ++axis) toward[axis] = scaled[axis] - base[axis] < 0.5 ? -1 : 1;
    const double radius_sq = radius * radius;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Array3d cell(base.x() + ((corner & 1) ? toward.x() : 0.0),
                                base.y() + ((corner & 2) ? toward.y() : 0.0),
                                base.z() + ((corner & 4) ? toward.z() : 0.0));
      const auto found = cells_.find(KeyOf(cell));
      if (found == cells_.end()) continue;
      for (size_t j : found->second) {
        if (!taken[j] && (offsets_[j] - centre).squaredNorm() <= radius_sq) visit(j);
      }
    }
  }

  std::vector<size_t> Near(const Eigen::Vector3d& centre, const std::vector<bool>& taken) const {
    std::vector<size_t> near;
    ForEachNear(centre, radius_, taken, [&near](size_t j) { near.push_back(j); });
    return near;
  }
  int CountNear(const Eigen::Vector3d& centre, const std::vector<bool>& taken) const {
    int count = 0;
    ForEachNear(centre, radius_, taken, [&count](size_t) { ++count; });
    return count;
  }

 private:
  static int64_t KeyOf(const Eigen::Array3d& cell) {
    // 21 bits an axis: +-1 million cells, far beyond any building at centimetre radii.
    auto axis = [](double v) { return static_cast<int64_t>(v) & ((int64_t{1} << 21) - 1); };
    return axis(cell.x()) << 42 | axis(cell.y()) << 21 | axis(cell.z());
  }

  const std::vector<Eigen::Vector3d>& offsets_;
  double radius_;
  std::unordered_map<int64_t, std::vector<size_t>> cells_;
};

int DistinctOwners(const std::vector<size_t>& members, const std::vector<int>& owner) {
  std::vector<int> owners;
  for (size_t j : members) owners.push_back(owner[j]);
  std::sort(owners.begin(), owners.end());
  return static_cast<int>(std::unique(owners.begin(), owners.end()) - owners.begin());
}

Eigen::Vector3d MedianOffset(const std::vector<Eigen::Vector3d>& offsets,
                             const std::vector<size_t>& members) {
  Eigen::Vector3d median;
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> values;
    for (size_t j : members) values.push_back(offsets[j][axis]);
    std::nth_element(values.begin(),
                     values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
    median[axis] = values[values.size() / 2];
  }
  return median;
}

}  // namespace

std::vector<size_t> KeyframesAround(const Eigen::Vector3d& centre, const std::vector<size_t>& skip,
                                    const std::vector<LocatorKeyframe>& keyframes,
                                    const LocatorOptions& options) {
  std::vector<size_t> near;
  for (size_t slot = 0; slot < keyframes.size(); ++slot) {
    if (keyframes[slot].world_points.empty() || keyframes[slot].synthetic_view.valid() ||
        (keyframes[slot].world_from_cam.translation() - centre).norm() > options.copies.around_m ||
        std::find(skip.begin(), skip.end(), slot) != skip.end()) {
      continue;
    }
    near.push_back(slot);
  }
  // Farthest first in position and view direction (a turn of 1 radian counting as 1 m), from
  // the keyframe nearest the centre.
  auto apart = [&keyframes](size_t a, size_t b) {
    return (keyframes[a].world_from_cam.translation() - keyframes[b].world_from_cam.translation())
               .norm() +
           (keyframes[a].view_direction - keyframes[b].view_direction).norm();
  };
  std::vector<size_t> chosen;
  if (near.empty() || options.copies.around_keyframes <= 0) return chosen;
  chosen.push_back(*std::min_element(near.begin(), near.end(), [&](size_t a, size_t b) {
    return (keyframes[a].world_from_cam.translation() - centre).norm() <
           (keyframes[b].world_from_cam.translation() - centre).norm();
  }));
  std::vector<double> nearest_chosen(near.size(), std::numeric_limits<double>::infinity());
  while (static_cast<int>(chosen.size()) < options.copies.around_keyframes) {
    size_t next = near.size();
    double farthest = 0.0;
    for (size_t i = 0; i < near.size(); ++i) {
      nearest_chosen[i] = std::min(nearest_chosen[i], apart(near[i], chosen.back()));
      if (nearest_chosen[i] > farthest) {
        farthest = nearest_chosen[i];
        next = i;
      }
    }
    if (next == near.size()) break;  // every keyframe chosen
    chosen.push_back(near[next]);
  }
  return chosen;
}

std::vector<CopyOffset> CopyOffsets(const PlaceVerdict& winner, const std::vector<size_t>& searched,
                                    const std::vector<LocatorKeyframe>& keyframes,
                                    const LocatorOptions& options) {
  const cv::Mat& query = winner.inlier_descriptors;
  SIGHTMAP_CHECK(static_cast<size_t>(query.rows) == winner.inlier_points.size(),
                 "the winner holds " << query.rows << " inlier descriptors and "
                                     << winner.inlier_points.size() << " inlier points");
  std::vector<Eigen::Vector3d> offsets;
  std::vector<int> owner;  // per vote, the row of the winner's inlier that cast it
  if (options.copies.offsets <= 0 || query.empty()) return {};
  const double max_distance = GuidedMaxDistance(query, options);
  // At most max_voters inliers vote, evenly spread over them: matching is most of the stage's time,
  // and a few hundred find a copy as well as a thousand do.
  const int step = std::max(
      1, (query.rows + options.copies.max_voters - 1) / std::max(1, options.copies.max_voters));
  cv::Mat voters;
  std::vector<int> voter_row;
  for (int r = 0; r < query.rows; r += step) {
    voters.push_back(query.row(r));
    voter_row.push_back(r);
  }
  for (size_t slot : searched) {
    SIGHTMAP_CHECK(slot < keyframes.size(), "keyframe " << slot << " is not a keyframe slot");
    const LocatorKeyframe& look_alike = keyframes[slot];
    if (look_alike.descriptors.empty() || look_alike.descriptors.cols != query.cols ||
        look_alike.descriptors.type() != query.type()) {
      continue;
    }
    for (const std::vector<cv::DMatch>& nearest : KNearest(voters, look_alike.descriptors, 2)) {
      for (const cv::DMatch& match : nearest) {
        if (match.distance > max_distance) continue;
        const int row = voter_row[static_cast<size_t>(match.queryIdx)];
        const cv::Point3f& a = winner.inlier_points[static_cast<size_t>(row)];
        const cv::Point3f& b = look_alike.world_points[static_cast<size_t>(match.trainIdx)];
        const Eigen::Vector3d offset(b.x - a.x, b.y - a.y, b.z - a.z);
        if (offset.norm() <= options.same_pose_m) continue;
        offsets.push_back(offset);
        owner.push_back(row);
      }
    }
  }
  std::vector<CopyOffset> copies;
  const OffsetGrid grid(offsets, options.copies.cluster_m);
  std::vector<bool> taken(offsets.size(), false);
  // Per vote, the votes around it (not distinct voters: an inlier votes once a look-alike, and
  // the count is the cheaper; distinct voters decide the support below). Counted once, then
  // again only around what a round takes.
  std::vector<int> around(offsets.size());
  for (size_t i = 0; i < offsets.size(); ++i) around[i] = grid.CountNear(offsets[i], taken);
  // Modes are found by votes, most first, but kept by distinct voters: three times as many
  // modes as copies are asked are weighed (a mode whose votes come from too few inliers counts
  // too), and the best supported kept.
  for (int round = 0; round < 3 * options.copies.offsets; ++round) {
    size_t best = offsets.size();
    int most = 0;
    for (size_t i = 0; i < offsets.size(); ++i) {
      if (!taken[i] && around[i] > most) {
        most = around[i];
        best = i;
      }
    }
    if (best == offsets.size() || most < options.copies.min_support) break;
    std::vector<size_t> members = grid.Near(offsets[best], taken);
    CopyOffset copy;
    copy.offset = MedianOffset(offsets, members);
    // Around the median: the cluster may have been found off its centre.
    std::vector<size_t> centred = grid.Near(copy.offset, taken);
    if (!centred.empty()) {
      members = std::move(centred);
      copy.offset = MedianOffset(offsets, members);
    }
    copy.support = DistinctOwners(members, owner);
    for (size_t j : members) taken[j] = true;
    // The votes whose neighbourhood lost some: those within the radius of a taken one.
    std::vector<size_t> stale;
    for (size_t j : members) {
      grid.ForEachNear(offsets[j], options.copies.cluster_m, taken,
                       [&stale](size_t k) { stale.push_back(k); });
    }
    std::sort(stale.begin(), stale.end());
    stale.erase(std::unique(stale.begin(), stale.end()), stale.end());
    for (size_t k : stale) around[k] = grid.CountNear(offsets[k], taken);
    if (copy.support >= options.copies.min_support) copies.push_back(copy);
  }
  std::stable_sort(copies.begin(), copies.end(),
                   [](const CopyOffset& a, const CopyOffset& b) { return a.support > b.support; });
  if (static_cast<int>(copies.size()) > options.copies.offsets) {
    copies.resize(static_cast<size_t>(options.copies.offsets));
  }
  return copies;
}

Place PlaceSeeing(const Eigen::Isometry3d& world_from_cam, const Eigen::Vector3d& target,
                  const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options) {
  const Eigen::Vector3d direction = world_from_cam.linear().col(2);
  const double min_cos = std::cos(DegToRad(options.place_max_angle_deg));
  const double radius_sq = options.neighbour_radius_m * options.neighbour_radius_m;
  std::vector<std::pair<int, size_t>> seeing;  // points near the target, slot
  for (size_t slot = 0; slot < keyframes.size(); ++slot) {
    const LocatorKeyframe& keyframe = keyframes[slot];
    if (keyframe.synthetic_view.valid() ||
        (keyframe.world_from_cam.translation() - world_from_cam.translation()).norm() >
            options.copies.place_radius_m ||
        keyframe.view_direction.dot(direction) < min_cos) {
      continue;
    }
    int near = 0;
    for (const cv::Point3f& p : keyframe.world_points) {
      if ((Eigen::Vector3d(p.x, p.y, p.z) - target).squaredNorm() <= radius_sq) ++near;
    }
    if (near >= options.min_inliers) seeing.emplace_back(near, slot);
  }
  std::sort(seeing.begin(), seeing.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  Place place;
  const size_t size = std::min(seeing.size(), static_cast<size_t>(options.max_neighbours) + 1);
  for (size_t i = 0; i < size; ++i) place.slots.push_back(seeing[i].second);
  if (!place.slots.empty()) place.head = place.slots.front();
  return place;
}

namespace {

// The model side of a place's matches: every 3D feature of its keyframes, their descriptors
// (vconcat'ed, empty without points) and keyframes; and their vocabulary nodes when asked.
PlaceMatches PlacePoints(const Place& place, const std::vector<LocatorKeyframe>& keyframes,
                         std::vector<int>* model_nodes) {
  PlaceMatches matches;
  std::vector<cv::Mat> blocks;
  for (size_t s : place.slots) {
    const LocatorKeyframe& member = keyframes[s];
    if (member.world_points.empty()) continue;
    blocks.push_back(member.descriptors);
    matches.model_points.insert(matches.model_points.end(), member.world_points.begin(),
                                member.world_points.end());
    if (model_nodes)
      model_nodes->insert(model_nodes->end(), member.nodes.begin(), member.nodes.end());
    matches.model_slots.insert(matches.model_slots.end(), member.world_points.size(), s);
  }
  if (!blocks.empty()) cv::vconcat(blocks, matches.model_descriptors);
  return matches;
}

}  // namespace

PlaceMatches MatchPlaceFrom(const PreparedPhoto& photo, const Place& place,
                            const std::vector<LocatorKeyframe>& keyframes,
                            const PoseHypothesis& pose, const LocatorOptions& options) {
  PlaceMatches matches = PlacePoints(place, keyframes, /*model_nodes=*/nullptr);
  if (matches.model_points.empty() || photo.features.descriptors.empty()) return matches;
  int projected = 0;
  GuidedMatch(photo.features.descriptors, photo.points, photo.grid, matches.model_descriptors,
              matches.model_points, pose, GuidedMaxDistance(matches.model_descriptors, options),
              options.copies.search_radius_px, &matches.object, &matches.image,
              &matches.object_model, &projected);
  return matches;
}

PlaceMatches MatchPlace(const PreparedPhoto& photo, const Place& place,
                        const std::vector<LocatorKeyframe>& keyframes,
                        const LocatorOptions& options) {
  const bool bounded = !photo.nodes.empty();
  std::vector<int> model_nodes;
  PlaceMatches matches = PlacePoints(place, keyframes, bounded ? &model_nodes : nullptr);
  if (matches.model_points.size() < 2 || photo.features.descriptors.empty()) return matches;
  const cv::Mat& query = photo.features.descriptors;
  std::vector<std::vector<cv::DMatch>> knn;
  if (bounded) {
    knn = KnnWithinNodes(query, photo.nodes, matches.model_descriptors, model_nodes, 4);
  } else {
    knn = KNearest(query, matches.model_descriptors, 4);
  }
  const double same_point_sq = options.same_point_m * options.same_point_m;
  const double max_distance = MaxDistance(matches.model_descriptors, options);
  for (const std::vector<cv::DMatch>& neighbours : knn) {
    if (neighbours.empty()) continue;
    const cv::DMatch& nearest = neighbours[0];
    if (nearest.distance > max_distance) continue;
    const cv::Point3f& p = matches.model_points[static_cast<size_t>(nearest.trainIdx)];
    // The second-nearest that is another 3D point; the same point seen by a neighbour
    // keyframe confirms rather than competes.
    bool distinct = true;
    for (size_t n = 1; n < neighbours.size(); ++n) {
      const cv::Point3f d = matches.model_points[static_cast<size_t>(neighbours[n].trainIdx)] - p;
      if (d.dot(d) <= same_point_sq) continue;
      distinct = nearest.distance < options.match_ratio * neighbours[n].distance;
      break;
    }
    if (!distinct) continue;
    matches.object.push_back(p);
    matches.image.push_back(photo.points[static_cast<size_t>(nearest.queryIdx)]);
    matches.object_model.push_back(nearest.trainIdx);
  }
  return matches;
}

namespace {

// PnP over every intrinsics candidate; the one with most inliers wins.
PoseHypothesis BestOverIntrinsics(const PreparedPhoto& photo, const PlaceMatches& matches,
                                  const LocatorOptions& options) {
  PoseHypothesis found;
  for (const Intrinsics& k : photo.feature_candidates) {
    PoseHypothesis hypothesis = SolvePose(matches.object, matches.image, k, options);
    // Each candidate refined before they are compared: on a shallow scene a wrong focal length
    // fits nearly as many inliers as the right one until both are refined.
    if (hypothesis.valid && !photo.intrinsics_given && options.refine_estimated_focal) {
      RefineFocal(matches.object, matches.image, options, &hypothesis);
    }
    if (hypothesis.valid && (!found.valid || hypothesis.inliers.size() > found.inliers.size())) {
      found = std::move(hypothesis);
    }
  }
  return found;
}

// The place's keyframe holding most of the pose's inliers (ties: the lower slot); the place's
// head when none does.
size_t KeyframeOfMostInliers(const Place& place, const PlaceMatches& matches,
                             const std::vector<int>& object_model,
                             const std::vector<int>& inliers) {
  std::unordered_map<size_t, int> inliers_of_slot;
  for (int i : inliers) {
    ++inliers_of_slot[matches
                          .model_slots[static_cast<size_t>(object_model[static_cast<size_t>(i)])]];
  }
  size_t slot = place.head;
  int most = -1;
  for (const auto& [candidate, count] : inliers_of_slot) {
    if (count > most || (count == most && candidate < slot)) {
      slot = candidate;
      most = count;
    }
  }
  return slot;
}

}  // namespace

int RequiredInlierCells(const PreparedPhoto& photo, const LocatorOptions& options) {
  return std::clamp(photo.detail_cells / 2,
                    std::min(options.min_inlier_cells_few_detail, options.min_inlier_cells),
                    options.min_inlier_cells);
}

PlaceVerdict VerifyPlace(const PreparedPhoto& photo, const Place& place,
                         const PlaceMatches& matches, const std::vector<LocatorKeyframe>& keyframes,
                         const LocatorOptions& options) {
  PlaceVerdict verdict;
  verdict.verified_slot = place.head;
  PoseHypothesis found = BestOverIntrinsics(photo, matches, options);
  verdict.matches = static_cast<int>(matches.object.size());
  // Guided matching: the place's points projected with the first pose find their photo
  // keypoints in a small window, then the pose is refined on all of them. A right pose gains
  // many inliers; a pose fitted to chance matches (a similar room) finds few.
  const std::vector<cv::Point2f>* image = &matches.image;
  const std::vector<int>* object_model = &matches.object_model;
  std::vector<cv::Point3f> guided_object;
  std::vector<cv::Point2f> guided_image;
  std::vector<int> guided_model;
  if (found.valid && static_cast<int>(found.inliers.size()) >= options.min_ransac_inliers) {
    for (int round = 0; round < options.guided_rounds; ++round) {
      GuidedMatch(photo.features.descriptors, photo.points, photo.grid, matches.model_descriptors,
                  matches.model_points, found,
                  GuidedMaxDistance(matches.model_descriptors, options), options.guided_radius_px,
                  &guided_object, &guided_image, &guided_model, &verdict.projected);
      if (!RefineOn(guided_object, guided_image, options, &found)) break;
      verdict.matches = static_cast<int>(guided_object.size());
      // The inliers now index the guided correspondences.
      image = &guided_image;
      object_model = &guided_model;
    }
  }
  if (!found.valid) {
    verdict.pose = std::move(found);
    return verdict;
  }
  verdict.inliers = static_cast<int>(found.inliers.size());
  // What each inlier explains: its photo cell, its model point and descriptor.
  verdict.inlier_descriptors.create(verdict.inliers, matches.model_descriptors.cols,
                                    matches.model_descriptors.type());
  for (int k = 0; k < verdict.inliers; ++k) {
    const size_t i = static_cast<size_t>(found.inliers[static_cast<size_t>(k)]);
    const int cell = GridCell((*image)[i], photo.size.width, photo.size.height, kFineCells);
    verdict.inlier_fine_cells.push_back(static_cast<uint8_t>(cell));
    verdict.fine_cell_mask |= uint64_t{1} << cell;
    const int row = (*object_model)[i];
    const cv::Point3f& point = matches.model_points[static_cast<size_t>(row)];
    verdict.inlier_centroid += Eigen::Vector3d(point.x, point.y, point.z);
    verdict.inlier_points.push_back(point);
    matches.model_descriptors.row(row).copyTo(verdict.inlier_descriptors.row(k));
  }
  if (verdict.inliers > 0) verdict.inlier_centroid /= verdict.inliers;
  // The paper's check is against the retrieved keyframe the pose was verified on: the member of
  // the place holding most inliers (a place spans views up to ~100 deg apart, so its head may
  // face away from a right pose).
  verdict.verified_slot = KeyframeOfMostInliers(place, matches, *object_model, found.inliers);
  verdict.rotation_deg = RotationAngleDeg(keyframes[verdict.verified_slot].world_from_cam.linear(),
                                          found.world_from_cam.linear());
  verdict.cells = CoveredCells(*image, found.inliers, photo.size.width, photo.size.height);
  verdict.required_cells = RequiredInlierCells(photo, options);
  verdict.passed_other_checks = verdict.inliers >= options.min_inliers &&
                                verdict.rotation_deg <= options.max_rotation_from_keyframe_deg &&
                                verdict.cells >= verdict.required_cells &&
                                !HasLowInlierShare(verdict, options);
  verdict.accepted = verdict.passed_other_checks;
  verdict.pose = std::move(found);
  // Last: the keyframe's pixels must line up with the photo's. Measured on a pose the cheaper
  // checks refused too, when it holds min_inliers: such a pose still makes the photo ambiguous
  // (Decide), unless its view is unlike the photo.
  const LocatorKeyframe& verified = keyframes[verdict.verified_slot];
  if (verdict.inliers >= options.min_inliers && options.min_view_agreement > 0.0 &&
      verified.thumbnail && !photo.agreement_image.empty()) {
    verdict.agreement = MeasureViewAgreement(photo.agreement_image, verdict.pose.intrinsics,
                                             verdict.pose.world_from_cam, *verified.thumbnail,
                                             verified.world_from_cam, options.view_agreement);
    verdict.looks_different =
        verdict.agreement.judged && verdict.agreement.Score() < options.min_view_agreement;
    verdict.unconfirmed = verdict.accepted && !verdict.agreement.judged &&
                          verdict.inliers < options.min_inliers_unchecked;
    verdict.accepted = verdict.accepted && !verdict.looks_different && !verdict.unconfirmed;
  }
  return verdict;
}

std::vector<size_t> SecondOpinionKeyframes(const PlaceVerdict& verdict, const Place& place,
                                           const std::vector<LocatorKeyframe>& keyframes,
                                           const LocatorOptions& options) {
  const LocatorOptions::ViewSecondOpinion& second = options.view_second_opinion;
  const Eigen::Vector3d photo_position = verdict.pose.world_from_cam.translation();
  const Eigen::Vector3d photo_direction = verdict.pose.world_from_cam.linear().col(2);
  const double min_cos = std::cos(DegToRad(second.max_angle_deg));
  std::vector<std::pair<double, size_t>> near;
  for (const size_t slot : place.slots) {
    const LocatorKeyframe& keyframe = keyframes[slot];
    if (slot == verdict.verified_slot || !keyframe.thumbnail) continue;
    const double distance = (keyframe.world_from_cam.translation() - photo_position).norm();
    if (distance > second.radius_m || keyframe.view_direction.dot(photo_direction) < min_cos) {
      continue;
    }
    near.emplace_back(distance, slot);
  }
  std::sort(near.begin(), near.end());
  std::vector<size_t> slots = {verdict.verified_slot};
  for (size_t i = 0; i < near.size() && static_cast<int>(i) < second.keyframes; ++i) {
    slots.push_back(near[i].second);
  }
  return slots;
}

bool JudgeViewAgain(const PreparedPhoto& photo, const Place& place,
                    const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options,
                    PlaceVerdict* verdict) {
  if (options.view_second_opinion.keyframes <= 0 || !verdict->looks_different ||
      !verdict->passed_other_checks || verdict->ceiling_only || photo.agreement_image.empty() ||
      !keyframes[verdict->verified_slot].thumbnail) {
    return false;
  }
  const std::vector<size_t> slots = SecondOpinionKeyframes(*verdict, place, keyframes, options);
  if (slots.size() < 2) return false;  // the verified keyframe alone: its judgement stands
  std::vector<PlacedThumbnail> placed;
  for (const size_t slot : slots) {
    placed.push_back({keyframes[slot].thumbnail.get(), keyframes[slot].world_from_cam});
  }
  const ViewAgreement again =
      MeasureViewAgreement(photo.agreement_image, verdict->pose.intrinsics,
                           verdict->pose.world_from_cam, placed, options.view_agreement);
  if (!again.judged || again.Score() < options.min_view_agreement) return false;
  verdict->agreement = again;
  verdict->looks_different = false;
  verdict->accepted = true;
  return true;
}

bool PoseCovariance(const std::vector<cv::Point3f>& world_points,
                    const Eigen::Isometry3d& world_from_cam, const Intrinsics& intrinsics,
                    Eigen::Matrix<double, 6, 6>* covariance) {
  const Eigen::Matrix3d cam_from_world = world_from_cam.linear().transpose();
  const Eigen::Vector3d centre = world_from_cam.translation();
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  int used = 0;
  for (const cv::Point3f& point : world_points) {
    const Eigen::Vector3d x =
        cam_from_world * (Eigen::Vector3d(point.x, point.y, point.z) - centre);
    if (!(x.z() > 0.0)) continue;
    // Axial noise of a structured-light sensor at this range (Nguyen, Izadi, Lovell 2012).
    const double depth_sd_m = 0.0012 + 0.0019 * (x.z() - 0.4) * (x.z() - 0.4);
    const double point_sd_px = intrinsics.fx * depth_sd_m / x.z();
    const double weight = 1.0 / (1.0 + point_sd_px * point_sd_px);
    Eigen::Matrix<double, 2, 3> projection;
    projection << intrinsics.fx / x.z(), 0.0, -intrinsics.fx * x.x() / (x.z() * x.z()), 0.0,
        intrinsics.fy / x.z(), -intrinsics.fy * x.y() / (x.z() * x.z());
    Eigen::Matrix<double, 3, 6> motion;
    motion.leftCols<3>() = -cam_from_world;  // the camera centre moved in the world
    // x turned by a small rotation w about the camera's axes: x + w x x = x - [x]x w.
    motion.rightCols<3>() << 0.0, x.z(), -x.y(), -x.z(), 0.0, x.x(), x.y(), -x.x(), 0.0;
    const Eigen::Matrix<double, 2, 6> jacobian = projection * motion;
    information += weight * jacobian.transpose() * jacobian;
    ++used;
  }
  if (used < 3) return false;
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(information);
  if (!lu.isInvertible()) return false;
  *covariance = lu.inverse();
  return true;
}

namespace {

// The pose with its camera centre moved by `shift` (world) [m] and turned by `turn` about the
// camera's own axes [rad].
Eigen::Isometry3d Slid(const Eigen::Isometry3d& world_from_cam, const Eigen::Vector3d& shift,
                       const Eigen::Vector3d& turn) {
  Eigen::Matrix3d cam_from_world = world_from_cam.linear().transpose();
  const double angle = turn.norm();
  if (angle > 0.0) {
    cam_from_world = Eigen::AngleAxisd(angle, turn / angle).toRotationMatrix() * cam_from_world;
  }
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.linear() = cam_from_world.transpose();
  moved.translation() = world_from_cam.translation() + shift;
  return moved;
}

// One round of the slide: the step along the spread's major axis that gains most, or nothing.
struct SlideStep {
  PoseHypothesis pose;
  std::vector<cv::Point3f> inlier_points;
};
// The direction a pose is free to slide in: its position's major axis, the turn per metre that
// keeps its inliers in place, and how far to look; nothing when it spreads outside slide's band.
struct WeakAxis {
  Eigen::Vector3d axis;
  Eigen::Vector3d turn_per_m;
  double reach_m = 0.0;
};
std::optional<WeakAxis> FindWeakAxis(const PoseHypothesis& pose,
                                     const std::vector<cv::Point3f>& inlier_points,
                                     const LocatorOptions::Slide& slide) {
  Eigen::Matrix<double, 6, 6> covariance;
  if (!PoseCovariance(inlier_points, pose.world_from_cam, pose.intrinsics, &covariance)) {
    return std::nullopt;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> position(covariance.topLeftCorner<3, 3>());
  const double sd = std::sqrt(std::max(0.0, position.eigenvalues()(2)));
  if (!(sd > slide.min_sd_m && sd < slide.max_sd_m)) return std::nullopt;
  WeakAxis weak;
  weak.axis = position.eigenvectors().col(2);
  weak.turn_per_m =
      covariance.bottomLeftCorner<3, 3>() * covariance.topLeftCorner<3, 3>().inverse() * weak.axis;
  weak.reach_m = std::min(slide.reach_sd * sd, slide.reach_m);
  return weak;
}

std::optional<SlideStep> BestStepAlongWeakAxis(const PreparedPhoto& photo,
                                               const PlaceMatches& points,
                                               const PoseHypothesis& from, const WeakAxis& weak,
                                               const LocatorOptions& options) {
  const LocatorOptions::Slide& slide = options.slide;
  const Eigen::Vector3d& axis = weak.axis;
  const Eigen::Vector3d& turn_per_m = weak.turn_per_m;
  const double reach = weak.reach_m;
  const int max_distance = GuidedMaxDistance(points.model_descriptors, options);
  // The place's points matched around `pose` and the pose refined on them; its inliers' points.
  const auto grow = [&](PoseHypothesis* pose) -> std::optional<std::vector<cv::Point3f>> {
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    std::vector<int> model;
    int projected = 0;
    GuidedMatch(photo.features.descriptors, photo.points, photo.grid, points.model_descriptors,
                points.model_points, *pose, max_distance, options.guided_radius_px, &object, &image,
                &model, &projected);
    if (!RefineOn(object, image, options, pose)) return std::nullopt;
    return Subset(object, pose->inliers);
  };
  std::optional<SlideStep> best;
  size_t most = from.inliers.size();
  for (int k = -slide.steps; k <= slide.steps; ++k) {
    if (k == 0) continue;
    const double along = reach * k / slide.steps;
    PoseHypothesis step = from;
    step.world_from_cam = Slid(from.world_from_cam, along * axis, along * turn_per_m);
    std::optional<std::vector<cv::Point3f>> grown = grow(&step);
    if (!grown) continue;
    const size_t inliers = step.inliers.size();
    if (inliers < most + static_cast<size_t>(slide.min_gain) || 10 * inliers < 11 * most) continue;
    most = inliers;
    best = SlideStep{step, std::move(*grown)};
  }
  if (!best) return best;
  // The step was grown from a pose a few pixels off; grown again from its refined pose, the
  // points that were just outside the window join.
  PoseHypothesis regrown = best->pose;
  std::optional<std::vector<cv::Point3f>> grown = grow(&regrown);
  if (grown && regrown.inliers.size() >= most) best = SlideStep{regrown, std::move(*grown)};
  return best;
}

}  // namespace

std::optional<PoseHypothesis> SlideAlongWeakAxis(const PreparedPhoto& photo, const Place& place,
                                                 const std::vector<LocatorKeyframe>& keyframes,
                                                 const PlaceVerdict& winner,
                                                 const LocatorOptions& options) {
  if (!winner.pose.valid || options.slide.min_sd_m <= 0.0 || photo.features.descriptors.empty()) {
    return std::nullopt;
  }
  // The place's points are gathered only for a pose that spreads: most winners do not.
  PlaceMatches points;
  std::optional<SlideStep> current;
  for (int round = 0; round < options.slide.rounds; ++round) {
    const PoseHypothesis& from = current ? current->pose : winner.pose;
    const std::optional<WeakAxis> weak =
        FindWeakAxis(from, current ? current->inlier_points : winner.inlier_points, options.slide);
    if (!weak) break;
    if (points.model_points.empty()) {
      points = PlacePoints(place, keyframes, /*model_nodes=*/nullptr);
      if (points.model_points.empty()) return std::nullopt;
    }
    std::optional<SlideStep> next = BestStepAlongWeakAxis(photo, points, from, *weak, options);
    if (!next) break;
    current = std::move(next);
  }
  if (!current) return std::nullopt;
  return current->pose;
}

void JudgeViewsAgain(const PreparedPhoto& photo, const std::vector<Place>& places,
                     const std::vector<LocatorKeyframe>& keyframes, const LocatorOptions& options,
                     std::vector<PlaceVerdict>* verdicts) {
  SIGHTMAP_CHECK(verdicts->size() <= places.size(), "JudgeViewsAgain: a verdict without a place");
  const auto accepted = [](const PlaceVerdict& verdict) { return verdict.accepted; };
  if (std::any_of(verdicts->begin(), verdicts->end(), accepted)) return;
  for (size_t i = 0; i < verdicts->size(); ++i) {
    JudgeViewAgain(photo, places[i], keyframes, options, &(*verdicts)[i]);
  }
}

bool HasLowInlierShare(const PlaceVerdict& verdict, const LocatorOptions& options) {
  // With the right pose a good share of the place's points that land in the photo find their
  // keypoint; a pose fitted to a texture that repeats elsewhere finds few beyond it.
  return verdict.projected > 0 && verdict.inliers < options.min_inlier_share * verdict.projected;
}

bool RestsOnCeilingOnly(const PlaceVerdict& verdict, const Eigen::Vector3d& world_up,
                        const LocatorOptions& options) {
  if (options.ceiling_only_max_thickness_m <= 0.0 || !verdict.pose.valid ||
      verdict.inlier_points.empty()) {
    return false;
  }
  const Eigen::Vector3d up = world_up.normalized();
  std::vector<double> heights;
  heights.reserve(verdict.inlier_points.size());
  for (const cv::Point3f& point : verdict.inlier_points) {
    heights.push_back(up.dot(Eigen::Vector3d(point.x, point.y, point.z)));
  }
  std::sort(heights.begin(), heights.end());
  const auto percentile = [&](double share) {
    return heights[static_cast<size_t>(share * static_cast<double>(heights.size() - 1))];
  };
  const double camera_height = up.dot(verdict.pose.world_from_cam.translation());
  return percentile(0.9) - percentile(0.1) <= options.ceiling_only_max_thickness_m &&
         percentile(0.1) > camera_height;
}

namespace {

// The verdict with a pose and most inliers (the first of equals), among the accepted ones only
// when `accepted_only`; null when there is none.
const PlaceVerdict* MostInliers(const std::vector<PlaceVerdict>& verdicts, bool accepted_only) {
  const PlaceVerdict* best = nullptr;
  for (const PlaceVerdict& verdict : verdicts) {
    if (accepted_only && !verdict.accepted) continue;
    if (verdict.pose.valid && verdict.inliers > (best ? best->inliers : 0)) best = &verdict;
  }
  return best;
}

// Why nothing was matched, from the refused verdict with most inliers: the check it failed, in
// VerifyPlace's order.
Refusal WhyNotMatched(const std::vector<PlaceVerdict>& verdicts, const LocatorOptions& options) {
  const PlaceVerdict* best = MostInliers(verdicts, /*accepted_only=*/false);
  std::ostringstream why;
  const int most_inliers = best ? best->inliers : 0;
  if (best && most_inliers >= options.min_inliers &&
      best->rotation_deg > options.max_rotation_from_keyframe_deg) {
    why << "the best pose (" << most_inliers << " inliers) turns "
        << std::lround(best->rotation_deg) << " deg from its keyframe (at most "
        << options.max_rotation_from_keyframe_deg << " allowed).";
    return Refusal{UnmatchedReason::kUnseenView, why.str()};
  }
  why << "none of " << verdicts.size() << " retrieved places gave a pose: " << most_inliers
      << " PnP inliers at best";
  if (best && most_inliers >= options.min_inliers) {
    if (best->cells < best->required_cells) {
      why << " but in " << best->cells << " cells of the photo (" << best->required_cells
          << " needed).";
      return Refusal{UnmatchedReason::kMatchesInOneCorner, why.str()};
    }
    if (HasLowInlierShare(*best, options)) {
      why << ", only " << std::fixed << std::setprecision(1)
          << 100.0 * most_inliers / best->projected << "% of the " << best->projected
          << " model points its pose puts in the photo (" << 100.0 * options.min_inlier_share
          << "% needed).";
      return Refusal{UnmatchedReason::kFewMatches, why.str()};
    }
    if (best->unconfirmed) {
      why.str("");
      why << "the best pose (" << most_inliers
          << " inliers) could not be checked: too little of the model seen from it lands in the "
             "photo, and a pose with fewer than "
          << options.min_inliers_unchecked << " inliers needs the check.";
      return Refusal{UnmatchedReason::kFewMatches, why.str()};
    }
    if (best->ceiling_only) {
      std::ostringstream ceiling;
      ceiling << "the best pose (" << most_inliers
              << " inliers) rests on the ceiling alone, whose tiles and lights repeat across the "
                 "building: include a wall or furniture in the photo.";
      return Refusal{UnmatchedReason::kBareView, ceiling.str()};
    }
    if (best->looks_different) {
      std::ostringstream different;
      different << std::fixed << std::setprecision(2) << "the best pose (" << most_inliers
                << " inliers) fits details that repeat elsewhere: the model seen from it is "
                   "unlike the photo (agreement "
                << best->agreement.Score() << ", " << options.min_view_agreement << " needed).";
      return Refusal{UnmatchedReason::kLooksDifferent, different.str()};
    }
  }
  why << ", " << options.min_inliers << " needed.";
  return Refusal{UnmatchedReason::kFewMatches, why.str()};
}

bool PosesDisagree(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                   const LocatorOptions& options) {
  return (a.translation() - b.translation()).norm() > options.same_pose_m ||
         RotationAngleDeg(a.linear(), b.linear()) > options.same_pose_deg;
}

// The view check's score, or -1 when it could not judge (a pose it cannot judge cannot lead).
double JudgedScore(const PlaceVerdict& verdict) {
  return verdict.agreement.judged ? verdict.agreement.Score() : -1.0;
}

// Whether `a` was judged and its view check scores at least `lead` above `b`'s.
bool ViewLeads(const PlaceVerdict& a, const PlaceVerdict& b, double lead) {
  return JudgedScore(a) >= 0.0 && JudgedScore(a) >= JudgedScore(b) + lead;
}

// Of poses that fit the photo about as well (`best` is accepted, `rivals` disagree with it), the
// one whose view check scores ambiguity_min_agreement_lead above every other pose placed elsewhere;
// null when the lead is smaller, a pose was not judged, or the leader is a rival a check refused.
// Every rival competes, not only the one of most inliers: where a box carries one picture on
// every face, two poses facing the wrong faces can outnumber the right one's inliers.
const PlaceVerdict* ViewLeader(const PlaceVerdict& best,
                               const std::vector<const PlaceVerdict*>& rivals,
                               const LocatorOptions& options) {
  const double lead = options.ambiguity_min_agreement_lead;
  if (lead <= 0.0) return nullptr;
  std::vector<const PlaceVerdict*> poses = {&best};
  poses.insert(poses.end(), rivals.begin(), rivals.end());
  for (const PlaceVerdict* pose : poses) {
    if (!pose->agreement.judged) return nullptr;
  }
  const PlaceVerdict* leader = *std::max_element(poses.begin(), poses.end(),
                                                 [](const PlaceVerdict* a, const PlaceVerdict* b) {
                                                   return JudgedScore(*a) < JudgedScore(*b);
                                                 });
  if (leader != &best && !leader->accepted) return nullptr;
  for (const PlaceVerdict* pose : poses) {
    if (pose != leader &&
        PosesDisagree(leader->pose.world_from_cam, pose->pose.world_from_cam, options) &&
        !ViewLeads(*leader, *pose, lead)) {
      return nullptr;
    }
  }
  return leader;
}

// A pose elsewhere with min_inlier_ratio_over_runner_up x the answer's inliers that the view check
// refused, yet scored at least ambiguity_min_doubted_agreement: it half looks like the photo, and
// the answer fits too little more than a repeated detail to outweigh it. Null when none.
const PlaceVerdict* StrongerDoubtedPose(const std::vector<PlaceVerdict>& verdicts,
                                        const PlaceVerdict& answer, const LocatorOptions& options) {
  if (options.ambiguity_min_doubted_agreement <= 0.0) return nullptr;
  const PlaceVerdict* doubted = nullptr;
  for (const PlaceVerdict& verdict : verdicts) {
    if (!verdict.looks_different || verdict.ceiling_only || verdict.copy ||
        JudgedScore(verdict) < options.ambiguity_min_doubted_agreement ||
        verdict.inliers < options.min_inlier_ratio_over_runner_up * answer.inliers ||
        !PosesDisagree(answer.pose.world_from_cam, verdict.pose.world_from_cam, options)) {
      continue;
    }
    if (doubted == nullptr || verdict.inliers > doubted->inliers) doubted = &verdict;
  }
  return doubted;
}

// Whether a pose other than `best` may make the photo ambiguous: it has min_inliers, lies
// elsewhere, and is not one the view check found unlike the photo (it fits only the repeated
// details), on the ceiling alone, or a copy's (DecideAmongCopies judges those). A pose other checks
// refused still fits the photo, and with the inliers the view is as ambiguous as with an accepted
// one (measured on 200 photos: one wrong pose fewer, the same right ones).
bool CanRival(const PlaceVerdict& verdict, const PlaceVerdict& best,
              const LocatorOptions& options) {
  return &verdict != &best && verdict.pose.valid && verdict.inliers >= options.min_inliers &&
         !verdict.looks_different && !verdict.ceiling_only && !verdict.copy &&
         PosesDisagree(best.pose.world_from_cam, verdict.pose.world_from_cam, options);
}

// Whether `rival` has about as many inliers as `best`: more than
// 1 / min_inlier_ratio_over_runner_up of its count.
bool FitsAboutAsWell(const PlaceVerdict& best, const PlaceVerdict& rival,
                     const LocatorOptions& options) {
  return static_cast<double>(best.inliers) <
         options.min_inlier_ratio_over_runner_up * rival.inliers;
}

}  // namespace

std::optional<Decision> DecideAmongCopies(const std::vector<PlaceVerdict>& verdicts,
                                          size_t best_index, const LocatorOptions& options) {
  SIGHTMAP_CHECK(best_index < verdicts.size(),
                 "verdict " << best_index << " of " << verdicts.size());
  const PlaceVerdict& best = verdicts[best_index];
  std::vector<const PlaceVerdict*> rivals = {&best};
  for (const PlaceVerdict& verdict : verdicts) {
    if (&verdict != &best && verdict.accepted && (verdict.copy || best.copy) &&
        PosesDisagree(best.pose.world_from_cam, verdict.pose.world_from_cam, options)) {
      rivals.push_back(&verdict);
    }
  }
  if (rivals.size() == 1) return std::nullopt;
  std::stable_sort(rivals.begin(), rivals.end(), [](const PlaceVerdict* a, const PlaceVerdict* b) {
    return JudgedScore(*a) > JudgedScore(*b);
  });
  const PlaceVerdict& leader = *rivals[0];
  const PlaceVerdict& second = *rivals[1];
  Decision decision;
  decision.runner_up_inliers = second.inliers;
  decision.runner_up_pose = second.pose.world_from_cam;
  if (ViewLeads(leader, second, options.copies.min_agreement_lead)) {
    decision.winner = static_cast<int>(&leader - verdicts.data());
    return decision;
  }
  std::ostringstream why;
  why << std::fixed << std::setprecision(1) << "the building has a copy of what the photo shows "
      << (leader.pose.world_from_cam.translation() - second.pose.world_from_cam.translation())
             .norm()
      << " m away, and the photo looks like both (" << leader.inliers << " and " << second.inliers
      << " inliers): the view is ambiguous; include something that tells them apart.";
  decision.refusal = Refusal{UnmatchedReason::kAmbiguous, why.str()};
  decision.ambiguous = {static_cast<int>(&leader - verdicts.data()),
                        static_cast<int>(&second - verdicts.data())};
  return decision;
}

namespace {

Decision DecideWinner(const std::vector<PlaceVerdict>& verdicts, const LocatorOptions& options) {
  Decision decision;
  const PlaceVerdict* winner = MostInliers(verdicts, /*accepted_only=*/true);
  if (winner == nullptr) {
    decision.refusal = WhyNotMatched(verdicts, options);
    return decision;
  }
  decision.winner = static_cast<int>(winner - verdicts.data());
  const PlaceVerdict& best = *winner;
  if (std::optional<Decision> among_copies =
          DecideAmongCopies(verdicts, static_cast<size_t>(decision.winner), options)) {
    return *among_copies;
  }
  // The poses elsewhere, accepted or not, and the strongest of them.
  std::vector<const PlaceVerdict*> rivals;
  const PlaceVerdict* runner_up = nullptr;
  for (const PlaceVerdict& verdict : verdicts) {
    if (!CanRival(verdict, best, options)) continue;
    rivals.push_back(&verdict);
    if (runner_up == nullptr || verdict.inliers > runner_up->inliers) runner_up = &verdict;
  }
  if (runner_up == nullptr) return decision;
  decision.runner_up_inliers = runner_up->inliers;
  decision.runner_up_pose = runner_up->pose.world_from_cam;
  const double apart_m =
      (best.pose.world_from_cam.translation() - runner_up->pose.world_from_cam.translation())
          .norm();
  std::ostringstream why;
  why << std::fixed << std::setprecision(1);
  if (FitsAboutAsWell(best, *runner_up, options)) {
    // About as many inliers: of every such pose, the one that looks clearly more like the photo
    // wins (a rival only when it passed every check).
    rivals.erase(std::remove_if(rivals.begin(), rivals.end(),
                                [&](const PlaceVerdict* rival) {
                                  return !FitsAboutAsWell(best, *rival, options);
                                }),
                 rivals.end());
    if (const PlaceVerdict* leader = ViewLeader(best, rivals, options)) {
      if (leader != &best) {
        decision.winner = static_cast<int>(leader - verdicts.data());
        decision.runner_up_inliers = best.inliers;
        decision.runner_up_pose = best.pose.world_from_cam;
      }
      return decision;
    }
    why << "two places fit the photo about as well (" << best.inliers << " and "
        << runner_up->inliers << " inliers, " << apart_m << " m apart): the view is ambiguous.";
  } else if (UniqueInlierShare(best, *runner_up) < options.min_unique_inlier_share &&
             (best.inlier_centroid - runner_up->inlier_centroid).norm() > options.same_pose_m) {
    // More inliers, but on the same part of the photo and on other things: the model repeats
    // itself there (identical desks), and the count says only which copy the walk saw better. (On
    // the same things, the two poses differ by the focal length tried, with estimated intrinsics.)
    why << "two places fit the same part of the photo (" << best.inliers << " and "
        << runner_up->inliers << " inliers, " << apart_m
        << " m apart): the view is ambiguous; include something that tells them apart.";
  } else {
    return decision;
  }
  decision.refusal = Refusal{UnmatchedReason::kAmbiguous, why.str()};
  decision.ambiguous = {decision.winner, static_cast<int>(runner_up - verdicts.data())};
  decision.winner = -1;
  return decision;
}

}  // namespace

Decision Decide(const std::vector<PlaceVerdict>& verdicts, const LocatorOptions& options) {
  Decision decision = DecideWinner(verdicts, options);
  if (decision.winner < 0) return decision;
  const PlaceVerdict& answer = verdicts[static_cast<size_t>(decision.winner)];
  const PlaceVerdict* doubted = StrongerDoubtedPose(verdicts, answer, options);
  if (doubted == nullptr) return decision;
  std::ostringstream why;
  why << std::fixed << std::setprecision(1) << "a place "
      << (answer.pose.world_from_cam.translation() - doubted->pose.world_from_cam.translation())
             .norm()
      << " m away fits " << doubted->inliers << " of the photo's features against the answer's "
      << answer.inliers << ", and looks partly like it (agreement " << std::setprecision(2)
      << doubted->agreement.Score()
      << "): the view is ambiguous; include something that tells them apart.";
  decision.refusal = Refusal{UnmatchedReason::kAmbiguous, why.str()};
  decision.ambiguous = {decision.winner, static_cast<int>(doubted - verdicts.data())};
  decision.runner_up_inliers = doubted->inliers;
  decision.runner_up_pose = doubted->pose.world_from_cam;
  decision.winner = -1;
  return decision;
}

Refusal ExplainBareView(Refusal refusal, int photo_detail_cells, const LocatorOptions& options) {
  const UnmatchedReason code = refusal.code;
  const bool matching_failed =
      code == UnmatchedReason::kUnknownPlace || code == UnmatchedReason::kUnseenView ||
      code == UnmatchedReason::kFewMatches || code == UnmatchedReason::kMatchesInOneCorner ||
      code == UnmatchedReason::kLooksDifferent;
  if (!matching_failed || photo_detail_cells > options.bare_view_max_detail_cells) return refusal;
  refusal.reason = "the photo shows little detail (its features fill " +
                   std::to_string(photo_detail_cells) + " of 16 parts of it); " + refusal.reason;
  refusal.code = UnmatchedReason::kBareView;
  return refusal;
}

const PlaceVerdict* WouldBeAnswer(const std::vector<PlaceVerdict>& verdicts) {
  const PlaceVerdict* winner = MostInliers(verdicts, /*accepted_only=*/true);
  return winner != nullptr ? winner : MostInliers(verdicts, /*accepted_only=*/false);
}

}  // namespace sightmap::identify
