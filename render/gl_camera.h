// OpenCV's camera model in OpenGL's fixed pipeline: the eye frame and the projections both
// renderers draw with, so that a camera point lands on the pixel Intrinsics::Project gives it
// (pixel centres at integers, row 0 at the top of the read-back image).
#pragma once

#include <Eigen/Core>

#include "core/camera.h"

namespace sightmap::render {

// GL eye from OpenCV camera: OpenGL's eye frame has y up and z backward; OpenCV's camera frame
// has y down, z forward.
Eigen::Matrix4d GlEyeFromCam();

// Clip from GL eye coordinates for a pinhole camera `k` seeing depths near_m to far_m (along
// z_cam, > 0): pixel (u, v) goes to window coordinates (u + 0.5, height - v - 0.5).
Eigen::Matrix4d GlPerspective(const Intrinsics& k, double near_m, double far_m);

// The same for a parallel projection: u = cx + fx x_cam, v = cy + fy y_cam [fx, fy in px / m].
Eigen::Matrix4d GlOrthographic(const Intrinsics& k, double near_m, double far_m);

}  // namespace sightmap::render
