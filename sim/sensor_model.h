// What turns an ideal rendering into a Kinect v1 / PrimeSense-like RGB-D frame.
//
// Depth (applied in this order to the rendered distance along the optical axis):
//  1. Projector shadow. The IR pattern comes from an emitter `projector_offset_m` to the camera's
//     +x (7.5 cm on a Kinect v1); surfaces the emitter cannot see behind a foreground object get no
//     depth. With registered depth this shows as a band without depth beside the object's edge on
//     the side away from the emitter (left in the image for an emitter on the right), as wide as
//     f * b * (1/z_near - 1/z_far).
//  2. No return from glass and glossy screens (Material::no_depth).
//  3. Dropouts at depth discontinuities (a 4-neighbour differs by more than
//     `discontinuity_relative` * z; dropped with probability `discontinuity_dropout`) and at
//     grazing angles (incidence between `grazing_start_deg` and `grazing_max_deg` drops with a
//     linearly rising probability, always beyond).
//  4. Axial noise and quantisation in disparity steps (Khoshelham & Elberink 2012; Nguyen et al.
//     2012): the sensor measures disparity d = f_b / z [px] in 1/8-px steps, so depth comes in
//     steps of delta(z) = z^2 * step / f_b. Gaussian noise is added in disparity so that the total
//     standard deviation of depth, quantisation included, is sigma(z) = axial_noise_coeff * z^2
//     (1.425e-3 z^2 m: 1.4 mm at 1 m, 5.7 mm at 2 m, 12.8 mm at 3 m).
//  5. Valid range [min_depth_m, max_depth_m]; an invalid border (registration leaves the image
//     edges without depth); millimetre output.
// Colour: motion blur along the image motion during the exposure, an exposure gain, and sensor
// noise with a read-noise floor plus shot noise growing with the square root of the signal.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/camera.h"

namespace sightmap::sim {

struct DepthSensorOptions {
  double min_depth_m = 0.5;  // closest measurable depth [m]
  // Farthest reported depth [m]. PrimeSense-class sensors return depth to about 8 m (the real
  // 3dmatch-lounge frames reach 7.8 m, 30% of their pixels beyond 4.5 m); the noise above makes
  // such depth coarse (9 cm at 8 m), and its users weigh it by that noise.
  double max_depth_m = 8.0;
  double axial_noise_coeff = 1.425e-3;  // sigma(z) = coeff * z^2 [1/m]
  // IR focal length times emitter-camera baseline [px * m] (580 px * 7.5 cm on a Kinect v1).
  double focal_baseline_px_m = 43.5;
  double disparity_step_px = 0.125;      // disparity quantisation [px]
  double projector_offset_m = 0.075;     // emitter position along camera +x [m]; 0 = no shadows
  double discontinuity_relative = 0.04;  // jump / z that counts as a discontinuity
  double discontinuity_dropout = 0.6;    // probability of losing a pixel on a discontinuity
  double grazing_start_deg = 70.0;       // incidence where dropouts begin [deg]
  double grazing_max_deg = 84.0;         // incidence beyond which nothing is measured [deg]
  // Invalid border [px]: registering depth to colour leaves bands of the colour image that the
  // depth camera does not see. Measured on the real recordings (columns or rows more than 90%
  // without depth): 3dmatch-lounge left 2-5, right 35-36, top 13, bottom 8; kinect-12f.oni left
  // 14, right 35, top 39, bottom 2.
  int border_left_px = 8;
  int border_right_px = 35;
  int border_top_px = 20;
  int border_bottom_px = 5;

  bool Check(std::string* error) const;
  // The model's total depth standard deviation at depth z [m].
  double DepthStdDev(double z_m) const { return axial_noise_coeff * z_m * z_m; }
  // Depth quantisation step at z [m].
  double DepthStep(double z_m) const { return z_m * z_m * disparity_step_px / focal_baseline_px_m; }
};

struct ColorSensorOptions {
  double read_noise = 2.5;        // noise floor [8-bit levels, 1 sigma]
  double shot_noise = 0.35;       // sigma = shot_noise * sqrt(level) on top of the floor
  double exposure_s = 0.008;      // exposure time used for motion blur [s]
  double max_blur_px = 12.0;      // longest blur streak [px]
  double defocus_sigma_px = 0.0;  // optics softness, Gaussian sigma [px]; 0 = none

  bool Check(std::string* error) const;
};

// Ideal depth (CV_32F metres, 0 = nothing) and no-depth mask (CV_8U) to CV_16U millimetres.
cv::Mat SimulateDepth(const cv::Mat& depth_m, const cv::Mat& no_depth_mask,
                      const Intrinsics& intrinsics, const DepthSensorOptions& options,
                      uint64_t seed);

// Ideal BGR to sensor BGR. `blur_px` is the image motion of the scene during the exposure [px];
// `gain` scales the exposure (1 = as rendered).
cv::Mat SimulateColor(const cv::Mat& bgr, double gain, const Eigen::Vector2d& blur_px,
                      const ColorSensorOptions& options, uint64_t seed);

}  // namespace sightmap::sim
