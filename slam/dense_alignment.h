// Dense RGB-D alignment of two frames from a rough pose: OpenCV's RgbdICPOdometry (point-to-plane
// ICP plus photometric error over image pyramids) on grey and depth images at a fraction of the
// sensor's size, and the information of the result from the point-to-plane geometry it converged
// on.
//
// Why it follows feature registration: features place a pair from a few hundred keypoints whose
// depth errs by sigma(z) = 1.4e-3 z^2, so a pair a second apart is off by about 1 cm and 0.2
// degrees. ICP uses every pixel's depth and the surfaces' normals. Measured on the simulated
// office walk (seed 11, 1,736 odometry links and 171 loops against ground truth), starting from
// the features' pose at 320x240: the median link error falls from 10 mm to 2 mm for odometry and
// from 9 mm to 3 mm for loops, and ICP is the better of the two for 90% of odometry links. At
// 160x120 the loops' median is 5 mm, and depth-only ICP (no photometric term) gives 4 mm at
// 320x240.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"

namespace sightmap::slam {

struct DenseAlignmentOptions {
  // Images are reduced to 1/downscale of the sensor's size (grey by area, depth by nearest
  // sample so depth edges stay sharp); 2 gives 320x240 for a 640x480 sensor, 230 KB a frame.
  int downscale = 2;
  // Iterations per pyramid level, finest first (so its length is the number of levels). Two
  // levels suit a start within a centimetre or two (a feature registration): the 80x60 and 40x30
  // levels of OpenCV's default (7, 7, 7, 10) can carry a correct start away, and the finer levels
  // do not bring it back. Started at the true pose, pairs 0.1-1 s apart on the hand-held walk
  // (seed 11, frames 150-600) ended at worst 41-118 mm and 4.8-7.7 degrees off with four levels
  // (before a wall with a window), 10-22 mm and 0.4-1.0 degrees with two; the mapped walk's ATE
  // fell from 0.059 to 0.047 m (seed 23: 0.054 to 0.036 m).
  std::vector<int> iterations_per_level = {7, 10};
  // Depth outside this range is not used: too near for the sensor, or too noisy for ICP [m].
  double min_depth_m = 0.4;
  double max_depth_m = 6.0;
  // Pixels whose grey gradient (Sobel magnitude) is below this take no part in the photometric
  // error, per pyramid level, finest first (as iterations_per_level). OpenCV's default, 10,
  // leaves out pale prints and wood grain, the only texture on a wall a metre away that holds a
  // slide along it: on the robot walk (seed 11, 10 Hz, tracked) 3 instead of 10 took the ATE from
  // 0.0271 to 0.0217 m (5: 0.0239, 1: 0.0234). The coarse level keeps 10, as pale texture there
  // narrows the basin (a start 8 cm off then stays 2.4 cm off instead of reaching 0.3 mm). The
  // simulator's frames have 95% of their pixels above 3 and 60% above 10, the real lounge frames
  // 79% and 61%.
  std::vector<double> min_gradient_per_level = {3.0, 10.0};
  // The information of the result: every information_stride_px-th pixel of the source (in the
  // reduced image) that lands within max_pair_distance_m of the target's surface contributes
  // its point-to-plane residual, weighted by the axial depth noise sigma(z) = depth_noise_coeff
  // x z^2 [1/m] (the same model as registration).
  int information_stride_px = 2;
  double max_pair_distance_m = 0.05;
  double depth_noise_coeff = 1.425e-3;
  // Fewer paired pixels than this cannot support a pose: the alignment is refused.
  int min_pairs = 500;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const DenseAlignmentOptions& options);
void from_json(const nlohmann::json& json, DenseAlignmentOptions& options);

// A frame reduced for dense alignment. Empty when the frame has none (a restored keyframe whose
// colour was not loaded): alignment is then skipped by the callers.
struct DenseImage {
  cv::Mat gray;      // CV_8UC1
  cv::Mat depth_mm;  // CV_16UC1 [mm], 0 where unmeasured

  bool empty() const { return gray.empty() || depth_mm.empty(); }
  size_t bytes() const { return gray.total() * gray.elemSize() + depth_mm.total() * 2; }
};

// A DenseImage stored losslessly as two PNGs (about half the size): how a map keeps the images
// of keyframes it aligns only as loop candidates, decoded when one is.
struct PackedDenseImage {
  std::vector<uint8_t> gray_png;
  std::vector<uint8_t> depth_png;

  bool empty() const { return gray_png.empty() || depth_png.empty(); }
  size_t bytes() const { return gray_png.size() + depth_png.size(); }
};
PackedDenseImage Pack(const DenseImage& image);
// Throws sightmap::Error when the bytes are not a packed DenseImage.
DenseImage Unpack(const PackedDenseImage& packed);

// Reduces a colour (BGR 8-bit) and registered depth (16-bit mm) image of the camera's size.
// Throws InvalidArgument for images that do not fit the camera or a downscale that does not divide
// its size.
DenseImage MakeDenseImage(const cv::Mat& color, const cv::Mat& depth_mm, const Intrinsics& camera,
                          const DenseAlignmentOptions& options);

struct DenseAlignment {
  bool success = false;
  std::string failure;  // why it was refused, when !success
  // Maps points of the source camera into the target camera.
  Eigen::Isometry3d target_from_source = Eigen::Isometry3d::Identity();
  // Inverse covariance, translation (x, y, z) then a small rotation applied on the left
  // (registration's convention). Singular along directions the geometry does not fix (a bare
  // wall leaves its two in-plane translations and the turn about its normal free).
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  int pairs = 0;  // source pixels that found the target's surface
  // Of the source pixels with depth that land inside the target image, the share that found its
  // surface, and the pairs' point-to-plane RMS normalised by their depth noise (about 1 when the
  // surfaces agree as well as the sensor allows).
  double pair_fraction = 0.0;
  double normalised_rms = 0.0;
};

// How well two frames agree at a given pose, over the source pixels (every
// information_stride_px-th) that land within max_pair_distance_m of the target's surface.
struct DenseFit {
  int pairs = 0;
  double pair_fraction = 0.0;   // as DenseAlignment's
  double normalised_rms = 0.0;  // as DenseAlignment's
  // RMS difference of the paired pixels' grey levels [8-bit levels]: what tells a pose that slid
  // along a textured surface from the right one, which point-to-plane distances cannot.
  double intensity_rms = 0.0;
};

// Aligns frames of one camera. Holds OpenCV's odometry object, whose normal estimator costs more
// to set up for an image size than an alignment does, so one aligner serves a whole map. Not
// thread-safe (OpenCV caches the estimator inside): one aligner per thread.
class DenseAligner {
 public:
  // Throws InvalidArgument for invalid options or a downscale that does not divide the camera's
  // size.
  DenseAligner(const Intrinsics& camera, const DenseAlignmentOptions& options);
  ~DenseAligner();
  DenseAligner(const DenseAligner&) = delete;
  DenseAligner& operator=(const DenseAligner&) = delete;

  // An image with what alignment computes of it (pyramids, points, normals, 3-4 MB at 320x240),
  // so that a frame aligned several times (a keyframe against its neighbours) is prepared once.
  class Frame;
  std::shared_ptr<Frame> Prepare(const DenseImage& image) const;

  // Aligns `source` to `target` (both made with this aligner's options from frames of its
  // camera), starting from `initial` (target_from_source). Refusal is a result: too little valid
  // depth, no convergence, or too few pairs.
  DenseAlignment Align(const DenseImage& source, const DenseImage& target,
                       const Eigen::Isometry3d& initial) const;
  DenseAlignment Align(Frame& source, Frame& target, const Eigen::Isometry3d& initial) const;

  // The agreement of `source` and `target` at `target_from_source`, without moving it.
  DenseFit Fit(Frame& source, Frame& target, const Eigen::Isometry3d& target_from_source) const;

  const DenseAlignmentOptions& options() const { return options_; }

 private:
  struct Impl;
  Intrinsics camera_;
  DenseAlignmentOptions options_;
  std::unique_ptr<Impl> impl_;
};

// `aligned` (target_from_source) in the directions its point-to-plane information fixes and
// `prior` in those it leaves nearly free: the eigen-directions of the information, rotations
// scaled by lever_m so that both count metres at that distance, weaker than min_eigen_ratio of
// the strongest. Why: before a single wall the geometry fixes its normal and two tilts, and ICP
// slides along the wall by whatever the faint texture and the depth noise pull it to (1-3 cm a
// 4 cm step on the robot walk, started at the true pose, while the information claims 0.1 mm).
// A ratio of 0 returns `aligned`.
Eigen::Isometry3d KeepPriorWhereWeak(const Eigen::Isometry3d& aligned,
                                     const Eigen::Matrix<double, 6, 6>& information,
                                     const Eigen::Isometry3d& prior, double min_eigen_ratio,
                                     double lever_m);

// Whether `information` fixes the rotation: every eigen-direction weaker than min_eigen_ratio of
// the strongest (rotations scaled by lever_m, as KeepPriorWhereWeak) is mostly a translation.
// Before a single wall the turn about its normal is free, and an alignment started from a guess
// tens of degrees off keeps most of that error.
bool FixesRotation(const Eigen::Matrix<double, 6, 6>& information, double min_eigen_ratio,
                   double lever_m);

}  // namespace sightmap::slam
