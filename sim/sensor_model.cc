#include "sim/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "sim/random.h"

namespace sightmap::sim {

bool DepthSensorOptions::Check(std::string* error) const {
  if (!(min_depth_m > 0.0 && max_depth_m > min_depth_m)) {
    *error = "need 0 < min_depth_m < max_depth_m";
    return false;
  }
  if (axial_noise_coeff < 0.0 || focal_baseline_px_m <= 0.0 || disparity_step_px < 0.0) {
    *error = "noise coefficient and disparity step must be >= 0, focal_baseline_px_m > 0";
    return false;
  }
  if (discontinuity_relative <= 0.0 || discontinuity_dropout < 0.0 || discontinuity_dropout > 1.0) {
    *error = "discontinuity_relative must be > 0 and discontinuity_dropout in [0, 1]";
    return false;
  }
  if (!(grazing_start_deg > 0.0 && grazing_max_deg > grazing_start_deg && grazing_max_deg <= 90)) {
    *error = "need 0 < grazing_start_deg < grazing_max_deg <= 90";
    return false;
  }
  if (std::min({border_left_px, border_right_px, border_top_px, border_bottom_px}) < 0) {
    *error = "borders must be >= 0";
    return false;
  }
  return true;
}

bool ColorSensorOptions::Check(std::string* error) const {
  if (read_noise < 0.0 || shot_noise < 0.0 || exposure_s < 0.0 || max_blur_px < 0.0 ||
      defocus_sigma_px < 0.0) {
    *error = "colour noise, exposure, blur and defocus must be >= 0";
    return false;
  }
  return true;
}

cv::Mat SimulateDepth(const cv::Mat& depth_m, const cv::Mat& no_depth_mask, const Intrinsics& k,
                      const DepthSensorOptions& options, uint64_t seed) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(depth_m.type() == CV_32F && no_depth_mask.type() == CV_8U &&
                     depth_m.size() == no_depth_mask.size(),
                 "SimulateDepth needs CV_32F depth and a CV_8U mask of the same size");
  const int w = depth_m.cols;
  const int h = depth_m.rows;
  cv::Mat keep(h, w, CV_8U, cv::Scalar(255));

  // 1. Projector shadow, row by row: a pixel is shadowed when a pixel to its emitter side maps
  //    to the same or a smaller emitter column (something closer blocks the emitter's ray).
  if (options.projector_offset_m != 0.0) {
    const double shift = k.fx * options.projector_offset_m;
    const bool emitter_right = options.projector_offset_m > 0.0;
    for (int v = 0; v < h; ++v) {
      const float* z = depth_m.ptr<float>(v);
      uint8_t* kp = keep.ptr<uint8_t>(v);
      double extreme = emitter_right ? std::numeric_limits<double>::infinity()
                                     : -std::numeric_limits<double>::infinity();
      for (int i = 0; i < w; ++i) {
        const int u = emitter_right ? w - 1 - i : i;
        if (z[u] <= 0.0f) continue;
        const double ue = u - shift / z[u];
        if (emitter_right ? ue >= extreme : ue <= extreme) {
          kp[u] = 0;
        } else {
          extreme = ue;
        }
      }
    }
  }

  // 2.-5. Per row, in parallel; each row draws from its own random stream so the result does not
  //       depend on the number of threads.
  const double cos_start = std::cos(options.grazing_start_deg * M_PI / 180.0);
  const double cos_max = std::cos(options.grazing_max_deg * M_PI / 180.0);
  const double fb = options.focal_baseline_px_m;
  const double step = options.disparity_step_px;
  cv::Mat out(h, w, CV_16U, cv::Scalar(0));
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      cv::RNG rng(MixSeed(seed, static_cast<uint64_t>(v)));
      const float* z = depth_m.ptr<float>(v);
      const uint8_t* no_depth = no_depth_mask.ptr<uint8_t>(v);
      uint8_t* kp = keep.ptr<uint8_t>(v);
      uint16_t* o = out.ptr<uint16_t>(v);
      const bool row_in_border = v < options.border_top_px || v >= h - options.border_bottom_px;
      const double y = (v - k.cy) / k.fy;  // ray (x, y, 1) through the pixel
      for (int u = 0; u < w; ++u) {
        if (z[u] <= 0.0f || no_depth[u] || !kp[u]) continue;
        if (row_in_border || u < options.border_left_px || u >= w - options.border_right_px) {
          continue;
        }
        if (u > 0 && v > 0 && u < w - 1 && v < h - 1) {
          const float zl = z[u - 1], zr = z[u + 1];
          const float zu = depth_m.ptr<float>(v - 1)[u], zd = depth_m.ptr<float>(v + 1)[u];
          const float jump = static_cast<float>(options.discontinuity_relative) * z[u];
          const bool discontinuity = std::abs(zl - z[u]) > jump || std::abs(zr - z[u]) > jump ||
                                     std::abs(zu - z[u]) > jump || std::abs(zd - z[u]) > jump;
          if (discontinuity) {
            if (rng.uniform(0.0, 1.0) < options.discontinuity_dropout) continue;
          } else {
            // Surface normal from the back-projected neighbours, against the viewing ray.
            const double x = (u - k.cx) / k.fx;
            const double dx = 1.0 / k.fx, dy = 1.0 / k.fy;
            const Eigen::Vector3d horizontal((x + dx) * zr - (x - dx) * zl, y * (zr - zl), zr - zl);
            const Eigen::Vector3d vertical(x * (zd - zu), (y + dy) * zd - (y - dy) * zu, zd - zu);
            const Eigen::Vector3d normal = horizontal.cross(vertical);
            const Eigen::Vector3d ray(x, y, 1.0);
            const double norm = normal.norm() * ray.norm();
            if (norm > 0.0) {
              const double cos_incidence = std::abs(normal.dot(ray)) / norm;
              if (cos_incidence < cos_max) continue;
              if (cos_incidence < cos_start &&
                  rng.uniform(0.0, 1.0) < (cos_start - cos_incidence) / (cos_start - cos_max)) {
                continue;
              }
            }
          }
        }
        // Noise in disparity; quantisation contributes delta^2 / 12 of the variance.
        const double z0 = z[u];
        const double sigma = options.DepthStdDev(z0);
        const double delta = options.DepthStep(z0);
        const double gauss_sigma = std::sqrt(std::max(sigma * sigma - delta * delta / 12.0, 0.0));
        double disparity = fb / z0 + rng.gaussian(gauss_sigma * fb / (z0 * z0));
        if (step > 0.0) disparity = std::round(disparity / step) * step;
        if (disparity <= 0.0) continue;
        const double zm = fb / disparity;
        if (zm < options.min_depth_m || zm > options.max_depth_m) continue;
        o[u] = static_cast<uint16_t>(std::lround(zm * 1000.0));
      }
    }
  });
  return out;
}

cv::Mat SimulateColor(const cv::Mat& bgr, double gain, const Eigen::Vector2d& blur_px,
                      const ColorSensorOptions& options, uint64_t seed) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(bgr.type() == CV_8UC3, "SimulateColor needs an 8-bit BGR image");
  cv::Mat image = bgr.clone();
  if (options.defocus_sigma_px > 0.0) {
    cv::GaussianBlur(image, image, cv::Size(0, 0), options.defocus_sigma_px);
  }
  const double length = std::min(blur_px.norm(), options.max_blur_px);
  if (length > 1.0) {
    // A line kernel along the motion: the average of the scene over the exposure.
    const int size = 2 * static_cast<int>(std::ceil(length / 2.0)) + 1;
    cv::Mat kernel(size, size, CV_32F, cv::Scalar(0));
    const Eigen::Vector2d dir = blur_px.normalized();
    const int samples = 4 * size;
    for (int i = 0; i < samples; ++i) {
      const double t = (static_cast<double>(i) / (samples - 1) - 0.5) * length;
      const int x = static_cast<int>(std::lround(size / 2 + t * dir.x()));
      const int y = static_cast<int>(std::lround(size / 2 + t * dir.y()));
      if (x >= 0 && y >= 0 && x < size && y < size) kernel.at<float>(y, x) += 1.0f;
    }
    kernel /= cv::sum(kernel)[0];
    cv::filter2D(image, image, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  }
  // Exposure gain, then read noise plus shot noise, per row with its own random stream.
  cv::Mat out(image.size(), CV_8UC3);
  const float read = static_cast<float>(options.read_noise);
  const float shot = static_cast<float>(options.shot_noise);
  const float g = static_cast<float>(gain);
  cv::parallel_for_(cv::Range(0, image.rows), [&](const cv::Range& rows) {
    std::vector<float> noise(static_cast<size_t>(image.cols) * 3);
    for (int v = rows.start; v < rows.end; ++v) {
      cv::RNG rng(MixSeed(seed, static_cast<uint64_t>(v)));
      cv::Mat noise_row(1, image.cols * 3, CV_32F, noise.data());
      rng.fill(noise_row, cv::RNG::NORMAL, 0.0, 1.0);
      const uint8_t* in = image.ptr<uint8_t>(v);
      uint8_t* o = out.ptr<uint8_t>(v);
      for (int i = 0; i < image.cols * 3; ++i) {
        const float level = g * in[i];
        const float value =
            level + noise[static_cast<size_t>(i)] * (read + shot * std::sqrt(level));
        o[i] = cv::saturate_cast<uint8_t>(value);
      }
    }
  });
  return out;
}

}  // namespace sightmap::sim
