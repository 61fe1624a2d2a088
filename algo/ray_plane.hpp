// SPDX-License-Identifier: Apache-2.0
// Target geometry of a calibration pose: for every main-camera pixel the
// undistorted viewing ray, and its intersection with the pose's plane.
#pragma once

#include <opencv2/core.hpp>

#include "algo/geometry.hpp"

namespace cylscan::algo {

// Unit viewing rays of every pixel of a camera (origin at the camera centre,
// camera frame), computed once per camera: undistortion with OpenCV's
// iterative model inversion run to convergence, not its default 5 steps.
class RayMap {
 public:
  explicit RayMap(const PinholeCamera& camera);

  cv::Size size() const { return rays_.size(); }
  const cv::Mat& rays() const { return rays_; }  // CV_64FC3, unit vectors
  cv::Vec3d ray(int u, int v) const { return rays_.at<cv::Vec3d>(v, u); }

 private:
  cv::Mat rays_;
};

// The points where the rays meet `plane` (plane in the camera frame, mm):
// CV_32FC3 of the camera's size, NaN where the pixel is masked out (`valid`:
// optional CV_8U, non-zero = use), the ray is parallel to the plane
// (|cos| < 1e-9) or the plane is behind the camera.
cv::Mat intersectRaysWithPlane(const RayMap& rays, const Plane& plane,
                               const cv::Mat& valid = cv::Mat());

}  // namespace cylscan::algo
