// SPDX-License-Identifier: Apache-2.0
// Small geometric value types shared by the calibration and metrology code:
// a pinhole camera with OpenCV distortion, a plane and a sphere. All lengths
// are millimetres in the frame the caller chooses (usually the main camera's).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace cylscan::algo {

// A camera of the OpenCV model: pixel = K · distort(x/z, y/z), with the
// distortion k1 k2 p1 p2 k3.
struct PinholeCamera {
  cv::Matx33d camera_matrix = cv::Matx33d::eye();
  cv::Vec<double, 5> dist_coeffs = cv::Vec<double, 5>::all(0.0);
  cv::Size image_size;
};

// The plane through `point` with unit `normal`: points X with normal·(X − point) = 0.
struct Plane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();

  double signedDistance(const Eigen::Vector3d& x) const { return normal.dot(x - point); }
};

struct Sphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;

  // Positive outside the sphere.
  double signedDistance(const Eigen::Vector3d& x) const { return (x - centre).norm() - radius; }
};

}  // namespace cylscan::algo
