// SPDX-License-Identifier: Apache-2.0
#include "algo/ray_plane.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/calib3d.hpp>

namespace cylscan::algo {

RayMap::RayMap(const PinholeCamera& camera) {
  const cv::Size size = camera.image_size;
  if (size.width <= 0 || size.height <= 0) throw std::invalid_argument("ray map: empty image size");
  std::vector<cv::Point2d> pixels;
  pixels.reserve(static_cast<std::size_t>(size.area()));
  for (int v = 0; v < size.height; ++v)
    for (int u = 0; u < size.width; ++u)
      pixels.emplace_back(u, v);
  std::vector<cv::Point2d> normalised;
  cv::undistortPoints(
      pixels, normalised, camera.camera_matrix, camera.dist_coeffs, cv::noArray(), cv::noArray(),
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  rays_.create(size, CV_64FC3);
  std::size_t i = 0;
  for (int v = 0; v < size.height; ++v) {
    auto* row = rays_.ptr<cv::Vec3d>(v);
    for (int u = 0; u < size.width; ++u, ++i) {
      const cv::Vec3d d(normalised[i].x, normalised[i].y, 1.0);
      row[u] = d / cv::norm(d);
    }
  }
}

cv::Mat intersectRaysWithPlane(const RayMap& rays, const Plane& plane, const cv::Mat& valid) {
  const cv::Size size = rays.size();
  if (!valid.empty() && (valid.type() != CV_8UC1 || valid.size() != size))
    throw std::invalid_argument("ray/plane: the validity mask must be CV_8UC1 of the image size");
  const double norm = plane.normal.norm();
  if (!(norm > 0.0)) throw std::invalid_argument("ray/plane: the plane normal is zero");
  const cv::Vec3d n(plane.normal.x() / norm, plane.normal.y() / norm, plane.normal.z() / norm);
  const double offset = n.dot(cv::Vec3d(plane.point.x(), plane.point.y(), plane.point.z()));
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

  cv::Mat out(size, CV_32FC3);
  for (int v = 0; v < size.height; ++v) {
    const auto* ray = rays.rays().ptr<cv::Vec3d>(v);
    const std::uint8_t* use = valid.empty() ? nullptr : valid.ptr<std::uint8_t>(v);
    auto* dst = out.ptr<cv::Vec3f>(v);
    for (int u = 0; u < size.width; ++u) {
      const double cosine = n.dot(ray[u]);
      const double t = offset / cosine;  // X = t·d, with n·X = offset
      if ((use && !use[u]) || !(std::abs(cosine) >= 1e-9) || !(t > 0.0)) {
        dst[u] = cv::Vec3f(kNaN, kNaN, kNaN);
        continue;
      }
      dst[u] = cv::Vec3f(static_cast<float>(t * ray[u][0]), static_cast<float>(t * ray[u][1]),
                         static_cast<float>(t * ray[u][2]));
    }
  }
  return out;
}

}  // namespace cylscan::algo
