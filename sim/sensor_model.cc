#include "sim/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "sim/random.h"

namespace sightmap::sim {

bool DepthSensorOptions::Check(std::string* error) const {
  if (!(min_depth_m > 0.0 && max_depth_m > min_depth_m && max_depth_m <= 65.535)) {
    *error = "need 0 < min_depth_m < max_depth_m <= 65.535 (depth is 16-bit millimetres)";
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

namespace {

// 1. Projector shadow, row by row: a pixel is shadowed when a pixel to its emitter side maps to
//    the same or a smaller emitter column (something closer blocks the emitter's ray).
void MarkProjectorShadow(const cv::Mat& depth_m, double focal_offset_px_m, cv::Mat* keep) {
  const bool emitter_right = focal_offset_px_m > 0.0;
  const int w = depth_m.cols;
  for (int v = 0; v < depth_m.rows; ++v) {
    const float* z = depth_m.ptr<float>(v);
    uint8_t* kp = keep->ptr<uint8_t>(v);
    double extreme = emitter_right ? std::numeric_limits<double>::infinity()
                                   : -std::numeric_limits<double>::infinity();
    for (int i = 0; i < w; ++i) {
      const int u = emitter_right ? w - 1 - i : i;
      if (z[u] <= 0.0f) continue;
      const double ue = u - focal_offset_px_m / z[u];
      if (emitter_right ? ue >= extreme : ue <= extreme) {
        kp[u] = 0;
      } else {
        extreme = ue;
      }
    }
  }
}

// The normalised image coordinates of the pixel grid, x = (u - cx) / fx a column and
// y = (v - cy) / fy a row, with their one-pixel neighbours x +- 1 / fx and y +- 1 / fy: computed
// once a frame rather than once a pixel (three divisions a pixel, which the compiler could not
// hoist past the random draws' calls, took 2.5 of the model's 11.7 ms a frame).
struct PixelGrid {
  PixelGrid(const Intrinsics& k, int width, int height) {
    const double dx = 1.0 / k.fx, dy = 1.0 / k.fy;
    for (int u = 0; u < width; ++u) {
      x.push_back((u - k.cx) / k.fx);
      x_right.push_back(x.back() + dx);
      x_left.push_back(x.back() - dx);
    }
    for (int v = 0; v < height; ++v) {
      y.push_back((v - k.cy) / k.fy);
      y_down.push_back(y.back() + dy);
      y_up.push_back(y.back() - dy);
    }
  }
  std::vector<double> x, x_right, x_left;
  std::vector<double> y, y_down, y_up;
};

// |cos| of the angle between the viewing ray (x, y, 1) and the surface normal from the
// back-projected 4-neighbours; -1 when they give no normal. Written out in the order Eigen's
// cross, dot and norm of 3-vectors evaluate (left to right), so the dropouts are those the Eigen
// expression gave; no branch, so the row's loop vectorises.
inline double IncidenceCosine(double x, double x_right, double x_left, double y, double y_down,
                              double y_up, float zl, float zr, float zu, float zd) {
  const double h0 = x_right * zr - x_left * zl;
  const double h1 = y * (zr - zl);
  const double h2 = zr - zl;
  const double v0 = x * (zd - zu);
  const double v1 = y_down * zd - y_up * zu;
  const double v2 = zd - zu;
  const double n0 = h1 * v2 - h2 * v1;
  const double n1 = h2 * v0 - h0 * v2;
  const double n2 = h0 * v1 - h1 * v0;
  const double norm = std::sqrt((n0 * n0 + n1 * n1) + n2 * n2) * std::sqrt((x * x + y * y) + 1.0);
  const double cosine = std::abs((n0 * x + n1 * y) + n2) / norm;
  return norm > 0.0 ? cosine : -1.0;
}

// std::round of x (half away from zero) where x >= 0, and some value <= 0 where x <= 0, without a
// call: adding and taking away 2^52 rounds to the nearest integer, ties to even, and the one tie
// that went down is moved up. Exact: x - r is representable (|x - r| <= 0.5).
inline double RoundHalfUp(double x) {
  constexpr double kTwo52 = 4503599627370496.0;  // from here on every double is an integer
  const double r = (x + kTwo52) - kTwo52;
  const double up = x - r == 0.5 ? r + 1.0 : r;
  return x < kTwo52 ? up : x;
}

// What a pixel of one row returns, decided in passes so that the random draws, which must come in
// column order from the row's stream, are the only serial part: geometry first, then the draws,
// then the noise arithmetic; the first and last are loops without branches or calls, vectorised.
enum class Return : uint8_t { kNone, kSure, kDiscontinuity, kGrazing };

struct RowScratch {
  explicit RowScratch(int width)
      : code(static_cast<size_t>(width), Return::kNone),
        cosine(static_cast<size_t>(width), 0.0),
        normal(static_cast<size_t>(width), 0.0) {}
  std::vector<Return> code;
  std::vector<double> cosine;  // |cos| of the incidence; a grazing pixel's dropout probability
  std::vector<double> normal;  // a returning pixel's standard normal draw
};

struct RowGeometry {
  const float* z;
  const float* z_up;    // nullptr on the image's first and last rows
  const float* z_down;  // nullptr on the image's first and last rows
  const uint8_t* no_depth;
  const uint8_t* keep;
};

// Pass one (a): the incidence of every pixel with four neighbours.
__attribute__((target_clones("avx2", "default"))) void RowIncidence(const RowGeometry& row,
                                                                    int u_begin, int u_end,
                                                                    const PixelGrid& grid, int v,
                                                                    double* cosine) {
  const double y = grid.y[static_cast<size_t>(v)];
  const double y_down = grid.y_down[static_cast<size_t>(v)];
  const double y_up = grid.y_up[static_cast<size_t>(v)];
  const double* x = grid.x.data();
  const double* x_right = grid.x_right.data();
  const double* x_left = grid.x_left.data();
  const float* z = row.z;
  const float* z_up = row.z_up;
  const float* z_down = row.z_down;
  for (int u = u_begin; u < u_end; ++u) {
    cosine[u] = IncidenceCosine(x[u], x_right[u], x_left[u], y, y_down, y_up, z[u - 1], z[u + 1],
                                z_up[u], z_down[u]);
  }
}

// The dropout thresholds of DepthSensorOptions in the form pass one compares, made once a frame.
struct DropoutThresholds {
  explicit DropoutThresholds(const DepthSensorOptions& options)
      : cos_start(std::cos(DegToRad(options.grazing_start_deg))),
        cos_max(std::cos(DegToRad(options.grazing_max_deg))),
        relative_jump(static_cast<float>(options.discontinuity_relative)) {}
  double cos_start;  // incidence where dropouts begin, as |cos|
  double cos_max;    // incidence beyond which nothing is measured, as |cos|
  float relative_jump;
};

// Pass one (b): projector shadow, no-return materials, discontinuities and incidence.
void ClassifyRow(const RowGeometry& row, int v, int u_begin, int u_end, int width,
                 const PixelGrid& grid, const DropoutThresholds& thresholds, RowScratch* scratch) {
  const bool inner_row = row.z_up != nullptr;
  const int inner_begin = std::max(u_begin, 1);
  const int inner_end = std::min(u_end, width - 1);
  if (inner_row && inner_begin < inner_end) {
    RowIncidence(row, inner_begin, inner_end, grid, v, scratch->cosine.data());
  }
  const double cos_start = thresholds.cos_start;
  const double cos_max = thresholds.cos_max;
  const float relative_jump = thresholds.relative_jump;
  const float* z = row.z;
  for (int u = u_begin; u < u_end; ++u) {
    const size_t i = static_cast<size_t>(u);
    Return& code = scratch->code[i];
    const float z0 = z[u];
    code = Return::kNone;
    if (z0 <= 0.0f || row.no_depth[u] || !row.keep[u]) continue;
    code = Return::kSure;
    if (!inner_row || u == 0 || u == width - 1) continue;
    const float jump = relative_jump * z0;
    if (std::abs(z[u - 1] - z0) > jump || std::abs(z[u + 1] - z0) > jump ||
        std::abs(row.z_up[u] - z0) > jump || std::abs(row.z_down[u] - z0) > jump) {
      code = Return::kDiscontinuity;
      continue;
    }
    double& cos_incidence = scratch->cosine[i];
    if (cos_incidence < 0.0 || cos_incidence >= cos_start) continue;
    if (cos_incidence < cos_max) {
      code = Return::kNone;
    } else {
      code = Return::kGrazing;
      cos_incidence = (cos_start - cos_incidence) / (cos_start - cos_max);
    }
  }
}

// Pass two: the row's draws in column order: a dropout draw where pass one left a chance, a
// standard normal for every pixel that returns (cv::RNG::gaussian(s) is that draw times s).
void DrawRow(int u_begin, int u_end, double discontinuity_dropout, cv::RNG* rng,
             RowScratch* scratch) {
  for (int u = u_begin; u < u_end; ++u) {
    const size_t i = static_cast<size_t>(u);
    Return& code = scratch->code[i];
    if (code == Return::kNone) continue;
    if ((code == Return::kDiscontinuity && rng->uniform(0.0, 1.0) < discontinuity_dropout) ||
        (code == Return::kGrazing && rng->uniform(0.0, 1.0) < scratch->cosine[i])) {
      code = Return::kNone;
      continue;
    }
    code = Return::kSure;
    scratch->normal[i] = rng->gaussian(1.0);
  }
}

// Pass three: noise in disparity and its quantisation, to millimetres (0 where nothing returns).
__attribute__((target_clones("avx2", "default"))) void MeasureRow(
    const float* z, int u_begin, int u_end, const DepthSensorOptions& options, const Return* code,
    const double* normal, uint16_t* out) {
  const double fb = options.focal_baseline_px_m;
  const double step = options.disparity_step_px;
  const double min_depth_m = options.min_depth_m;
  const double max_depth_m = options.max_depth_m;
  const bool quantise = step > 0.0;
  for (int u = u_begin; u < u_end; ++u) {
    // Quantisation contributes delta^2 / 12 of the variance.
    const double z0 = z[u];
    const double sigma = options.DepthStdDev(z0);
    const double delta = options.DepthStep(z0);
    const double gauss_sigma = std::sqrt(std::max(sigma * sigma - delta * delta / 12.0, 0.0));
    const double raw = fb / z0 + normal[u] * (gauss_sigma * fb / (z0 * z0));
    const double disparity = quantise ? RoundHalfUp(raw / step) * step : raw;
    const double zm = fb / disparity;
    const bool valid =
        code[u] == Return::kSure && disparity > 0.0 && zm >= min_depth_m && zm <= max_depth_m;
    // Check() keeps max_depth_m within 16-bit millimetres, so the integer conversion is exact.
    const int mm = static_cast<int>(RoundHalfUp(valid ? zm * 1000.0 : 0.0));
    out[u] = static_cast<uint16_t>(mm);
  }
}

// A colour row's exposure gain and sensor noise (standard normal draws given), to 8 bits as
// cv::saturate_cast does, rounded to nearest, ties to even (cvRound's conversion): clamped first,
// which gives the same bytes, then rounded by adding and taking away 2^23.
__attribute__((target_clones("avx2", "default"))) void AddNoiseRow(const uint8_t* in,
                                                                   const float* noise, int n,
                                                                   float gain, float read,
                                                                   float shot, uint8_t* out) {
  for (int i = 0; i < n; ++i) {
    const float level = gain * in[i];
    const float value = level + noise[i] * (read + shot * std::sqrt(level));
    const float clamped = std::min(std::max(value, 0.0f), 255.0f);
    constexpr float kTwo23 = 8388608.0f;  // from here on every float is an integer
    out[i] = static_cast<uint8_t>((clamped + kTwo23) - kTwo23);
  }
}

}  // namespace

cv::Mat SimulateDepth(const cv::Mat& depth_m, const cv::Mat& no_depth_mask, const Intrinsics& k,
                      const DepthSensorOptions& options, uint64_t seed) {
  SIGHTMAP_CHECK_OPTIONS(options);
  SIGHTMAP_CHECK(depth_m.type() == CV_32F && no_depth_mask.type() == CV_8U &&
                     depth_m.size() == no_depth_mask.size(),
                 "SimulateDepth needs CV_32F depth and a CV_8U mask of the same size");
  const int w = depth_m.cols;
  const int h = depth_m.rows;
  cv::Mat keep(h, w, CV_8U, cv::Scalar(255));
  if (options.projector_offset_m != 0.0) {
    MarkProjectorShadow(depth_m, k.fx * options.projector_offset_m, &keep);
  }

  // 2.-5. Per row, in parallel; each row draws from its own random stream so the result does not
  //       depend on the number of threads.
  const PixelGrid grid(k, w, h);
  const DropoutThresholds thresholds(options);
  const int u_begin = options.border_left_px;
  const int u_end = w - options.border_right_px;
  const int v_begin = options.border_top_px;
  const int v_end = h - options.border_bottom_px;
  cv::Mat out(h, w, CV_16U, cv::Scalar(0));
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    RowScratch scratch(w);
    for (int v = std::max(rows.start, v_begin); v < std::min(rows.end, v_end); ++v) {
      const bool inner_row = v > 0 && v < h - 1;
      const RowGeometry row{depth_m.ptr<float>(v), inner_row ? depth_m.ptr<float>(v - 1) : nullptr,
                            inner_row ? depth_m.ptr<float>(v + 1) : nullptr,
                            no_depth_mask.ptr<uint8_t>(v), keep.ptr<uint8_t>(v)};
      ClassifyRow(row, v, u_begin, u_end, w, grid, thresholds, &scratch);
      cv::RNG rng(MixSeed(seed, static_cast<uint64_t>(v)));
      DrawRow(u_begin, u_end, options.discontinuity_dropout, &rng, &scratch);
      MeasureRow(row.z, u_begin, u_end, options, scratch.code.data(), scratch.normal.data(),
                 out.ptr<uint16_t>(v));
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
      AddNoiseRow(image.ptr<uint8_t>(v), noise.data(), image.cols * 3, g, read, shot,
                  out.ptr<uint8_t>(v));
    }
  });
  return out;
}

}  // namespace sightmap::sim
