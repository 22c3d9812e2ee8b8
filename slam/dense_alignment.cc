#include "slam/dense_alignment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "core/rotation.h"

namespace sightmap::slam {
namespace {

using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Vector6 = Eigen::Matrix<double, 6, 1>;

// The camera of the reduced images; throws InvalidArgument when the downscale does not divide
// its size.
Intrinsics Reduced(const Intrinsics& camera, int downscale) {
  if (camera.width % downscale != 0 || camera.height % downscale != 0) {
    SIGHTMAP_THROW(InvalidArgument, "the dense downscale " << downscale << " must divide the "
                                                           << camera.width << "x" << camera.height
                                                           << " image");
  }
  return downscale == 1 ? camera
                        : camera.Scaled(camera.width / downscale, camera.height / downscale);
}

cv::Ptr<cv::rgbd::OdometryFrame> MakeOdometryFrame(const DenseImage& image,
                                                   const DenseAlignmentOptions& options) {
  cv::Mat depth_m;
  image.depth_mm.convertTo(depth_m, CV_32F, 1e-3);
  // OpenCV's odometry takes NaN, not 0, for a missing depth; its own range limits apply too, but
  // masking here keeps the information below on the same pixels.
  depth_m.setTo(std::numeric_limits<float>::quiet_NaN(), (image.depth_mm == 0) |
                                                             (depth_m < options.min_depth_m) |
                                                             (depth_m > options.max_depth_m));
  return cv::makePtr<cv::rgbd::OdometryFrame>(image.gray, depth_m);
}

Eigen::Vector3f PixelVector(const cv::Mat& image, int row, int col) {
  if (image.channels() == 3) {
    const cv::Vec3f v = image.at<cv::Vec3f>(row, col);
    return {v[0], v[1], v[2]};
  }
  const cv::Vec4f v = image.at<cv::Vec4f>(row, col);
  return {v[0], v[1], v[2]};
}

// A source pixel on the target's surface: its point moved into the target camera, the target
// pixel it lands on, the offset from the target's point there and that point's depth noise.
struct PixelPair {
  int row = 0;
  int col = 0;
  int u = 0;
  int v = 0;
  Eigen::Vector3d moved;
  Eigen::Vector3d offset;
  double sigma = 0.0;
};

// Calls visit(pair) for every information_stride_px-th source pixel with depth that lands inside
// the target image on a measured depth within max_pair_distance_m of its point. Returns how many
// source pixels landed inside the target image (the denominator of a pair fraction).
template <typename Visit>
int ForEachPair(const cv::Mat& source_depth_m, const cv::Mat& target_depth_m,
                const Intrinsics& camera, const Eigen::Isometry3d& target_from_source,
                const DenseAlignmentOptions& options, Visit&& visit) {
  int landed = 0;
  const int stride = options.information_stride_px;
  for (int row = 0; row < source_depth_m.rows; row += stride) {
    for (int col = 0; col < source_depth_m.cols; col += stride) {
      const float z = source_depth_m.at<float>(row, col);
      if (!std::isfinite(z)) continue;
      PixelPair pair;
      pair.row = row;
      pair.col = col;
      pair.moved = target_from_source * camera.Unproject(col, row, z);
      if (!(pair.moved.z() > 0.0)) continue;
      const Eigen::Vector2d pixel = camera.Project(pair.moved);
      pair.u = static_cast<int>(std::lround(pixel.x()));
      pair.v = static_cast<int>(std::lround(pixel.y()));
      if (pair.u < 0 || pair.v < 0 || pair.u >= target_depth_m.cols ||
          pair.v >= target_depth_m.rows) {
        continue;
      }
      ++landed;
      const float target_z = target_depth_m.at<float>(pair.v, pair.u);
      if (!std::isfinite(target_z)) continue;
      pair.offset = pair.moved - camera.Unproject(pair.u, pair.v, target_z);
      if (pair.offset.norm() > options.max_pair_distance_m) continue;
      pair.sigma = options.depth_noise_coeff * target_z * target_z;
      visit(pair);
    }
  }
  return landed;
}

// Sum of J^T J / sigma^2 over the point-to-plane residuals r = n . (T p - q) of source pixels
// that land on the target's surface where it has a normal, with J = [n^T, ((T p) x n)^T] for a
// perturbation applied on the left of T.
void PointToPlaneInformation(const cv::Mat& source_depth_m, const cv::Mat& target_depth_m,
                             const cv::Mat& target_normals, const Intrinsics& camera,
                             const DenseAlignmentOptions& options, DenseAlignment* result) {
  Matrix6 information = Matrix6::Zero();
  int pairs = 0;
  double squared = 0.0;
  const int landed = ForEachPair(
      source_depth_m, target_depth_m, camera, result->target_from_source, options,
      [&](const PixelPair& pair) {
        const Eigen::Vector3d normal = PixelVector(target_normals, pair.v, pair.u).cast<double>();
        if (!normal.allFinite() || normal.squaredNorm() < 0.25) return;
        Eigen::Matrix<double, 1, 6> jacobian;
        jacobian.leftCols<3>() = normal.transpose();
        jacobian.rightCols<3>() = pair.moved.cross(normal).transpose();
        information += jacobian.transpose() * jacobian / (pair.sigma * pair.sigma);
        const double residual = normal.dot(pair.offset) / pair.sigma;
        squared += residual * residual;
        ++pairs;
      });
  result->information = information;
  result->pairs = pairs;
  result->pair_fraction = landed > 0 ? static_cast<double>(pairs) / landed : 0.0;
  result->normalised_rms = pairs > 0 ? std::sqrt(squared / pairs) : 0.0;
}

}  // namespace

bool DenseAlignmentOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (downscale < 1) return fail("downscale must be at least 1");
  if (!(min_depth_m >= 0.0) || !(max_depth_m > min_depth_m)) {
    return fail("the depth range must satisfy 0 <= min_depth_m < max_depth_m");
  }
  if (iterations_per_level.empty() ||
      *std::min_element(iterations_per_level.begin(), iterations_per_level.end()) < 1) {
    return fail("iterations_per_level needs at least one level, each with at least 1 iteration");
  }
  if (min_gradient_per_level.size() != iterations_per_level.size() ||
      !std::all_of(min_gradient_per_level.begin(), min_gradient_per_level.end(),
                   [](double gradient) { return gradient >= 0.0; })) {
    return fail("min_gradient_per_level needs one value >= 0 per level of iterations_per_level");
  }
  if (information_stride_px < 1) return fail("information_stride_px must be at least 1");
  if (!(max_pair_distance_m > 0.0)) return fail("max_pair_distance_m must be positive");
  if (!(depth_noise_coeff > 0.0)) return fail("depth_noise_coeff must be positive");
  if (min_pairs < 6) return fail("min_pairs must be at least 6 (six unknowns)");
  return true;
}

PackedDenseImage Pack(const DenseImage& image) {
  SIGHTMAP_CHECK(!image.empty(), "an empty dense image cannot be packed");
  // Fast compression: packing runs once per keyframe on the mapping thread.
  const std::vector<int> fast = {cv::IMWRITE_PNG_COMPRESSION, 1};
  PackedDenseImage packed;
  SIGHTMAP_CHECK(cv::imencode(".png", image.gray, packed.gray_png, fast) &&
                     cv::imencode(".png", image.depth_mm, packed.depth_png, fast),
                 "could not encode a dense image");
  return packed;
}

DenseImage Unpack(const PackedDenseImage& packed) {
  DenseImage image;
  image.gray = cv::imdecode(packed.gray_png, cv::IMREAD_UNCHANGED);
  image.depth_mm = cv::imdecode(packed.depth_png, cv::IMREAD_UNCHANGED);
  SIGHTMAP_CHECK(image.gray.type() == CV_8UC1 && image.depth_mm.type() == CV_16UC1 &&
                     image.gray.size() == image.depth_mm.size(),
                 "a packed dense image does not decode to 8-bit grey and 16-bit depth");
  return image;
}

DenseImage MakeDenseImage(const cv::Mat& color, const cv::Mat& depth_mm, const Intrinsics& camera,
                          const DenseAlignmentOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  if (color.type() != CV_8UC3 || color.cols != camera.width || color.rows != camera.height ||
      depth_mm.type() != CV_16UC1 || depth_mm.size() != color.size()) {
    SIGHTMAP_THROW(InvalidArgument, "dense alignment needs 8-bit BGR colour and 16-bit depth of "
                                        << camera.width << "x" << camera.height);
  }
  const Intrinsics small = Reduced(camera, options.downscale);
  const cv::Size size(small.width, small.height);
  DenseImage image;
  cv::Mat gray;
  cv::cvtColor(color, gray, cv::COLOR_BGR2GRAY);
  if (options.downscale == 1) {
    image.gray = gray;
    image.depth_mm = depth_mm.clone();
  } else {
    cv::resize(gray, image.gray, size, 0.0, 0.0, cv::INTER_AREA);
    cv::resize(depth_mm, image.depth_mm, size, 0.0, 0.0, cv::INTER_NEAREST);
  }
  return image;
}

struct DenseAligner::Impl {
  Intrinsics small;
  cv::Ptr<cv::rgbd::RgbdICPOdometry> odometry;
};

DenseAligner::DenseAligner(const Intrinsics& camera, const DenseAlignmentOptions& options)
    : camera_(camera), options_(options), impl_(std::make_unique<Impl>()) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  impl_->small = Reduced(camera_, options_.downscale);
  const Intrinsics& small = impl_->small;
  const cv::Matx33d camera_matrix(small.fx, 0, small.cx, 0, small.fy, small.cy, 0, 0, 1);
  impl_->odometry = cv::makePtr<cv::rgbd::RgbdICPOdometry>(
      cv::Mat(camera_matrix), static_cast<float>(options_.min_depth_m),
      static_cast<float>(options_.max_depth_m), cv::rgbd::Odometry::DEFAULT_MAX_DEPTH_DIFF(),
      cv::rgbd::Odometry::DEFAULT_MAX_POINTS_PART(), options_.iterations_per_level,
      std::vector<float>(options_.min_gradient_per_level.begin(),
                         options_.min_gradient_per_level.end()));
}

DenseAligner::~DenseAligner() = default;

class DenseAligner::Frame {
 public:
  explicit Frame(cv::Ptr<cv::rgbd::OdometryFrame> frame) : frame_(std::move(frame)) {}
  cv::Ptr<cv::rgbd::OdometryFrame>& get() { return frame_; }

 private:
  cv::Ptr<cv::rgbd::OdometryFrame> frame_;
};

std::shared_ptr<DenseAligner::Frame> DenseAligner::Prepare(const DenseImage& image) const {
  const Intrinsics& small = impl_->small;
  SIGHTMAP_CHECK(!image.empty() && image.gray.cols == small.width &&
                     image.gray.rows == small.height && image.depth_mm.size() == image.gray.size(),
                 "dense alignment needs images made at 1/"
                     << options_.downscale << " of " << camera_.width << "x" << camera_.height);
  return std::make_shared<Frame>(MakeOdometryFrame(image, options_));
}

DenseAlignment DenseAligner::Align(const DenseImage& source, const DenseImage& target,
                                   const Eigen::Isometry3d& initial) const {
  return Align(*Prepare(source), *Prepare(target), initial);
}

DenseAlignment DenseAligner::Align(Frame& source, Frame& target,
                                   const Eigen::Isometry3d& initial) const {
  const Intrinsics& small = impl_->small;
  DenseAlignment result;
  cv::Ptr<cv::rgbd::OdometryFrame>& source_frame = source.get();
  cv::Ptr<cv::rgbd::OdometryFrame>& target_frame = target.get();
  cv::Mat init(4, 4, CV_64F);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) init.at<double>(r, c) = initial.matrix()(r, c);
  }
  cv::Mat rt;
  bool converged = false;
  try {
    converged = impl_->odometry->compute(source_frame, target_frame, rt, init);
  } catch (const cv::Exception&) {
    converged = false;  // too few valid pixels for OpenCV's solver
  }
  if (!converged || rt.empty()) {
    result.failure = "dense alignment did not converge";
    return result;
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) pose.matrix()(r, c) = rt.at<double>(r, c);
  }
  if (!pose.matrix().allFinite()) {
    result.failure = "dense alignment gave a non-finite pose";
    return result;
  }
  if (target_frame->normals.size() != target_frame->depth.size()) {
    result.failure = "dense alignment computed no normals";
    return result;
  }
  result.target_from_source = Orthonormalised(pose);
  PointToPlaneInformation(source_frame->depth, target_frame->depth, target_frame->normals, small,
                          options_, &result);
  if (result.pairs < options_.min_pairs) {
    result.failure = "dense alignment paired too few pixels (" + std::to_string(result.pairs) + ")";
    return result;
  }
  result.success = true;
  return result;
}

DenseFit DenseAligner::Fit(Frame& source, Frame& target,
                           const Eigen::Isometry3d& target_from_source) const {
  const cv::rgbd::OdometryFrame& source_frame = *source.get();
  const cv::rgbd::OdometryFrame& target_frame = *target.get();
  DenseFit fit;
  double squared = 0.0;
  double intensity_squared = 0.0;
  const int landed =
      ForEachPair(source_frame.depth, target_frame.depth, impl_->small, target_from_source,
                  options_, [&](const PixelPair& pair) {
                    // Along the line of sight: the target's normal is not needed to compare two
                    // poses.
                    const double residual = pair.offset.dot(pair.moved.normalized()) / pair.sigma;
                    squared += residual * residual;
                    const double difference =
                        static_cast<double>(source_frame.image.at<uint8_t>(pair.row, pair.col)) -
                        static_cast<double>(target_frame.image.at<uint8_t>(pair.v, pair.u));
                    intensity_squared += difference * difference;
                    ++fit.pairs;
                  });
  fit.pair_fraction = landed > 0 ? static_cast<double>(fit.pairs) / landed : 0.0;
  if (fit.pairs > 0) {
    fit.normalised_rms = std::sqrt(squared / fit.pairs);
    fit.intensity_rms = std::sqrt(intensity_squared / fit.pairs);
  }
  return fit;
}

SIGHTMAP_OPTIONS_JSON(DenseAlignmentOptions, downscale, iterations_per_level, min_depth_m,
                      max_depth_m, min_gradient_per_level, information_stride_px,
                      max_pair_distance_m, depth_noise_coeff, min_pairs)

namespace {

// Rotations scaled by lever_m, so that they and translations count metres at that distance.
Vector6 LeverScale(double lever_m) {
  Vector6 scale;
  scale << 1.0, 1.0, 1.0, lever_m, lever_m, lever_m;
  return scale;
}

// The eigen-directions of `information` in LeverScale(lever_m)'s units, weakest first.
Eigen::SelfAdjointEigenSolver<Matrix6> ScaledEigen(const Matrix6& information, double lever_m) {
  const Vector6 inverse_scale = LeverScale(lever_m).cwiseInverse();
  return Eigen::SelfAdjointEigenSolver<Matrix6>(inverse_scale.asDiagonal() * information *
                                                inverse_scale.asDiagonal());
}

}  // namespace

Eigen::Isometry3d KeepPriorWhereWeak(const Eigen::Isometry3d& aligned, const Matrix6& information,
                                     const Eigen::Isometry3d& prior, double min_eigen_ratio,
                                     double lever_m) {
  SIGHTMAP_CHECK(min_eigen_ratio >= 0.0 && lever_m > 0.0,
                 "KeepPriorWhereWeak needs a ratio >= 0 and a positive lever");
  if (min_eigen_ratio == 0.0) return aligned;
  // The information is on a perturbation applied on the left: aligned = [R(w) | t] prior.
  const Vector6 scale = LeverScale(lever_m);
  const Vector6 scaled = LogSe3(aligned * prior.inverse()).cwiseProduct(scale);
  const Eigen::SelfAdjointEigenSolver<Matrix6> eigen = ScaledEigen(information, lever_m);
  const double strongest = eigen.eigenvalues()(5);
  Vector6 kept = Vector6::Zero();
  for (int k = 0; k < 6; ++k) {
    if (!(eigen.eigenvalues()(k) >= min_eigen_ratio * strongest)) continue;
    const Vector6 direction = eigen.eigenvectors().col(k);
    kept += direction * direction.dot(scaled);
  }
  return Orthonormalised(ExpSe3(kept.cwiseQuotient(scale)) * prior);
}

bool FixesRotation(const Matrix6& information, double min_eigen_ratio, double lever_m) {
  SIGHTMAP_CHECK(min_eigen_ratio >= 0.0 && lever_m > 0.0,
                 "FixesRotation needs a ratio >= 0 and a positive lever");
  const Eigen::SelfAdjointEigenSolver<Matrix6> eigen = ScaledEigen(information, lever_m);
  const double strongest = eigen.eigenvalues()(5);
  if (!(strongest > 0.0)) return false;
  for (int k = 0; k < 6; ++k) {
    if (eigen.eigenvalues()(k) >= min_eigen_ratio * strongest) continue;
    if (eigen.eigenvectors().col(k).tail<3>().squaredNorm() > 0.5) return false;
  }
  return true;
}

}  // namespace sightmap::slam
