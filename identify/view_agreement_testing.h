// A textured wall for the view check's tests: rendered exactly from any camera, so a keyframe and
// a photo of it agree where the photo's pose is right and disagree where it is not.
#pragma once

#include <cmath>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera.h"
#include "core/rotation.h"

namespace sightmap::identify::testing {

// A camera at `position` turned yaw_deg about the y axis (down in the OpenCV camera frame): the
// locator tests' standpoints.
inline Eigen::Isometry3d PoseAt(const Eigen::Vector3d& position, double yaw_deg) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(DegToRad(yaw_deg), Eigen::Vector3d::UnitY()).matrix();
  pose.translation() = position;
  return pose;
}

// The plane z = wall_z_m of the world, its grey texture smooth blobs at 100 px/m over
// [-5, 5] m x [-5, 5] m (no period: a shifted view does not line up with itself).
class TexturedWall {
 public:
  explicit TexturedWall(double wall_z_m = 3.0, int seed = 4) : wall_z_m_(wall_z_m) {
    cv::Mat noise(40, 40, CV_32F);
    cv::RNG rng(static_cast<uint64_t>(seed));
    rng.fill(noise, cv::RNG::UNIFORM, 0.0, 255.0);
    cv::resize(noise, texture_, cv::Size(1000, 1000), 0, 0, cv::INTER_CUBIC);
    cv::Mat fine(200, 200, CV_32F);
    rng.fill(fine, cv::RNG::UNIFORM, -40.0, 40.0);
    cv::resize(fine, fine, texture_.size(), 0, 0, cv::INTER_LINEAR);
    texture_ += fine;
  }

  // Grey (CV_8UC1) and depth [mm] (CV_16UC1, 0 where the ray misses the wall) from a camera.
  void Render(const Eigen::Isometry3d& world_from_cam, const Intrinsics& k, cv::Mat* grey,
              cv::Mat* depth_mm) const {
    grey->create(k.height, k.width, CV_8UC1);
    depth_mm->create(k.height, k.width, CV_16UC1);
    grey->setTo(0);
    depth_mm->setTo(0);
    const Eigen::Vector3d centre = world_from_cam.translation();
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const Eigen::Vector3d ray_cam((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
        const Eigen::Vector3d ray = world_from_cam.linear() * ray_cam;
        if (std::abs(ray.z()) < 1e-9) continue;
        const double t = (wall_z_m_ - centre.z()) / ray.z();
        if (t <= 0.0) continue;
        const Eigen::Vector3d hit = centre + t * ray;
        const float tx = static_cast<float>((hit.x() + 5.0) * 100.0);
        const float ty = static_cast<float>((hit.y() + 5.0) * 100.0);
        if (tx < 0 || ty < 0 || tx >= texture_.cols - 1 || ty >= texture_.rows - 1) continue;
        cv::Mat sample;
        cv::getRectSubPix(texture_, cv::Size(1, 1), cv::Point2f(tx, ty), sample);
        grey->at<uint8_t>(v, u) = cv::saturate_cast<uint8_t>(sample.at<float>(0, 0));
        depth_mm->at<uint16_t>(v, u) = cv::saturate_cast<uint16_t>(1000.0 * t * ray_cam.z());
      }
    }
  }

 private:
  double wall_z_m_;
  cv::Mat texture_;  // CV_32F grey levels
};

// A TexturedWall with a board of another texture standing in front of it: the plane
// z = board_z_m between x = board_x0_m and board_x1_m (the furniture a photo is taken past).
class WallBehindBoard {
 public:
  WallBehindBoard(double wall_z_m = 3.0, double board_z_m = 1.8, double board_x0_m = -1.0,
                  double board_x1_m = 0.2)
      : wall_(wall_z_m), board_(board_z_m, /*seed=*/7), x0_(board_x0_m), x1_(board_x1_m) {}

  // As TexturedWall::Render; the board where a ray meets it before the wall.
  void Render(const Eigen::Isometry3d& world_from_cam, const Intrinsics& k, cv::Mat* grey,
              cv::Mat* depth_mm) const {
    wall_.Render(world_from_cam, k, grey, depth_mm);
    cv::Mat board_grey;
    cv::Mat board_depth;
    board_.Render(world_from_cam, k, &board_grey, &board_depth);
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const uint16_t z_mm = board_depth.at<uint16_t>(v, u);
        if (z_mm == 0) continue;
        const Eigen::Vector3d hit = world_from_cam * k.Unproject(u, v, 1e-3 * z_mm);
        if (hit.x() < x0_ || hit.x() > x1_) continue;
        grey->at<uint8_t>(v, u) = board_grey.at<uint8_t>(v, u);
        depth_mm->at<uint16_t>(v, u) = z_mm;
      }
    }
  }

 private:
  TexturedWall wall_;
  TexturedWall board_;
  double x0_;
  double x1_;
};

}  // namespace sightmap::identify::testing
