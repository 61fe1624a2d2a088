// SPDX-License-Identifier: Apache-2.0
// Synthetic ground truth for the calibration tests: pinhole cameras with their
// own (test-side) undistortion, a point-source cylindrical projector whose
// absolute phase is a known function of the 3D point, planes and spheres.
// Deliberately independent of algo/ray_plane so the two check each other.
#pragma once

#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "algo/geometry.hpp"

namespace cylscan::testing {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// A camera with the paper's field of view (1000×800, f ≈ 3478 px) scaled to
// `width` pixels, with an optional small distortion.
inline algo::PinholeCamera makeCamera(int width, int height, bool distorted) {
  const double f = 3.478 * width;
  algo::PinholeCamera c;
  c.camera_matrix =
      cv::Matx33d(f, 0, 0.5 * (width - 1) + 1.3, 0, f * 1.0005, 0.5 * (height - 1) - 0.7, 0, 0, 1);
  if (distorted) c.dist_coeffs = cv::Vec<double, 5>(-0.08, 0.12, 2e-4, -1.5e-4, 0.0);
  c.image_size = cv::Size(width, height);
  return c;
}

// Forward OpenCV distortion of normalised coordinates.
inline cv::Vec2d distort(const cv::Vec<double, 5>& k, cv::Vec2d p) {
  const double x = p[0];
  const double y = p[1];
  const double r2 = x * x + y * y;
  const double radial = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
  return {x * radial + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x),
          y * radial + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y};
}

// Unit ray of pixel (u, v) in the camera frame: Newton's method on the
// forward model with a numeric Jacobian, to 1e-15.
inline Eigen::Vector3d pixelRay(const algo::PinholeCamera& c, double u, double v) {
  const cv::Matx33d& k = c.camera_matrix;
  const double yd = (v - k(1, 2)) / k(1, 1);
  const double xd = (u - k(0, 2) - k(0, 1) * yd) / k(0, 0);
  cv::Vec2d p(xd, yd);
  for (int it = 0; it < 50; ++it) {
    const cv::Vec2d r = distort(c.dist_coeffs, p) - cv::Vec2d(xd, yd);
    if (std::abs(r[0]) + std::abs(r[1]) < 1e-16) break;
    const double h = 1e-7;
    const cv::Vec2d jx =
        (distort(c.dist_coeffs, p + cv::Vec2d(h, 0)) - distort(c.dist_coeffs, p)) / h;
    const cv::Vec2d jy =
        (distort(c.dist_coeffs, p + cv::Vec2d(0, h)) - distort(c.dist_coeffs, p)) / h;
    const double det = jx[0] * jy[1] - jy[0] * jx[1];
    p -= cv::Vec2d((jy[1] * r[0] - jy[0] * r[1]) / det, (-jx[1] * r[0] + jx[0] * r[1]) / det);
  }
  return Eigen::Vector3d(p[0], p[1], 1.0).normalized();
}

// First intersection (t > 0) of origin + t·dir with a plane or sphere.
inline std::optional<Eigen::Vector3d> hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                          const algo::Plane& plane) {
  const Eigen::Vector3d n = plane.normal.normalized();
  const double cosine = n.dot(dir);
  if (std::abs(cosine) < 1e-12) return std::nullopt;
  const double t = n.dot(plane.point - origin) / cosine;
  if (!(t > 0.0)) return std::nullopt;
  return origin + t * dir;
}

inline std::optional<Eigen::Vector3d> hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                          const algo::Sphere& sphere) {
  const Eigen::Vector3d oc = origin - sphere.centre;
  const double b = oc.dot(dir);
  const double c = oc.squaredNorm() - sphere.radius * sphere.radius;
  const double disc = b * b - c;
  if (disc < 0.0) return std::nullopt;
  const double t = -b - std::sqrt(disc);
  if (!(t > 0.0)) return std::nullopt;
  return origin + t * dir;
}

// The cylindrical projector: a point source on a vertical axis at (x, ·, z);
// the absolute phase of a lit point is a·azimuth + b with a = 2π/θh.
struct Projector {
  Eigen::Vector3d source{120.0, -20.0, -10.0};
  double gain = 2.0 * std::numbers::pi / (5.0 * std::numbers::pi / 180.0);  // 72 rad/rad
  double offset = 30.0;

  double phase(const Eigen::Vector3d& p) const {
    return gain * std::atan2(p.x() - source.x(), p.z() - source.z()) + offset;
  }
};

// A camera placed in the main frame: centre and rotation main→camera.
struct PlacedCamera {
  algo::PinholeCamera camera;
  cv::Matx33d rotation = cv::Matx33d::eye();  // X_cam = R·(X_main − centre)
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();

  Eigen::Vector3d rayInMain(int u, int v) const {
    const Eigen::Vector3d d = pixelRay(camera, u, v);
    const cv::Vec3d m = rotation.t() * cv::Vec3d(d.x(), d.y(), d.z());
    return {m[0], m[1], m[2]};
  }
};

// Phase map of a camera looking at one surface: NaN where the ray misses, or
// the point faces away from the camera or the projector's source.
template <class Surface>
cv::Mat renderPhase(const PlacedCamera& cam, const Surface& surface, const Projector& projector,
                    cv::Mat* truth_xyz = nullptr) {
  const cv::Size size = cam.camera.image_size;
  cv::Mat phase(size, CV_32FC1, cv::Scalar(kNaNf));
  if (truth_xyz) truth_xyz->create(size, CV_64FC3), truth_xyz->setTo(cv::Scalar::all(kNaN));
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      const Eigen::Vector3d dir = cam.rayInMain(u, v);
      const auto p = hit(cam.centre, dir, surface);
      if (!p) continue;
      if constexpr (std::is_same_v<Surface, algo::Sphere>) {
        const Eigen::Vector3d n = (*p - surface.centre).normalized();
        if (n.dot(projector.source - *p) <= 0.0) continue;  // in the projector's shadow
      }
      phase.at<float>(v, u) = static_cast<float>(projector.phase(*p));
      if (truth_xyz) truth_xyz->at<cv::Vec3d>(v, u) = cv::Vec3d(p->x(), p->y(), p->z());
    }
  }
  return phase;
}

// Rotation about the camera's y axis (a toe-in of the aux camera) then x.
inline cv::Matx33d rotationYX(double yaw_rad, double pitch_rad) {
  const double cy = std::cos(yaw_rad), sy = std::sin(yaw_rad);
  const double cx = std::cos(pitch_rad), sx = std::sin(pitch_rad);
  const cv::Matx33d ry(cy, 0, sy, 0, 1, 0, -sy, 0, cy);
  const cv::Matx33d rx(1, 0, 0, 0, cx, -sx, 0, sx, cx);
  return rx * ry;
}

inline Eigen::Vector3d planeNormal(double tilt_x_rad, double tilt_y_rad) {
  return Eigen::Vector3d(std::sin(tilt_y_rad), std::sin(tilt_x_rad), -1.0).normalized();
}

}  // namespace cylscan::testing
