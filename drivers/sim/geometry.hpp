// SPDX-License-Identifier: Apache-2.0
// Small geometry helpers of the virtual head (its own, shared with nothing in algo/).
#pragma once

#include <array>
#include <numbers>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace cylscan::sim {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

inline constexpr double kDeg = std::numbers::pi / 180.0;

inline Vec3 toVec(const std::array<double, 3>& a) {
  return {a[0], a[1], a[2]};
}
inline std::array<double, 3> toArray(const Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

// Rotation from a rotation vector in degrees (axis × angle), as in cv::Rodrigues.
inline Mat3 rotationFromVectorDeg(const std::array<double, 3>& r) {
  const Vec3 v = toVec(r) * kDeg;
  const double angle = v.norm();
  if (angle < 1e-15) return Mat3::Identity();
  return Eigen::AngleAxisd(angle, v / angle).toRotationMatrix();
}

// Rotation vector in degrees of a rotation matrix.
inline std::array<double, 3> rotationVectorDeg(const Mat3& r) {
  const Eigen::AngleAxisd aa(r);
  return toArray(aa.axis() * aa.angle() / kDeg);
}

// Angle wrapped into [0, 360).
inline double wrapDeg360(double a) {
  double w = a - 360.0 * static_cast<double>(static_cast<long long>(a / 360.0));
  if (w < 0) w += 360.0;
  if (w >= 360.0) w -= 360.0;
  return w;
}

struct Ray {
  Vec3 origin;
  Vec3 dir;  // unit
};

}  // namespace cylscan::sim
