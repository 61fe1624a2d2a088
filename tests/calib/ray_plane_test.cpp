// SPDX-License-Identifier: Apache-2.0
#include "algo/ray_plane.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>

#include "tests/calib/synthetic_scene.hpp"

namespace cylscan::algo {
namespace {

using testing::makeCamera;
using testing::pixelRay;

int countFinite(const cv::Mat& xyz) {
  int n = 0;
  for (auto it = xyz.begin<cv::Vec3f>(); it != xyz.end<cv::Vec3f>(); ++it)
    n += std::isfinite((*it)[0]);
  return n;
}

TEST(RayMap, RaysReprojectOntoTheirPixels) {
  const PinholeCamera camera = makeCamera(160, 128, true);
  const RayMap rays(camera);
  ASSERT_EQ(rays.size(), camera.image_size);
  std::vector<cv::Point3d> points;
  std::vector<cv::Point2d> pixels;
  double worst_angle = 0.0;
  for (int v = 0; v < 128; v += 7) {
    for (int u = 0; u < 160; u += 5) {
      const cv::Vec3d r = rays.ray(u, v);
      EXPECT_NEAR(cv::norm(r), 1.0, 1e-12);
      points.emplace_back(r[0] * 600, r[1] * 600, r[2] * 600);
      pixels.emplace_back(u, v);
      const Eigen::Vector3d own = pixelRay(camera, u, v);  // the test's own inversion
      // |a × b| = sin of the angle: acos near 1 would lose half the digits.
      worst_angle = std::max(worst_angle, own.cross(Eigen::Vector3d(r[0], r[1], r[2])).norm());
    }
  }
  std::vector<cv::Point2d> projected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera.camera_matrix,
                    camera.dist_coeffs, projected);
  double worst = 0.0;
  for (std::size_t i = 0; i < pixels.size(); ++i)
    worst = std::max(worst, cv::norm(projected[i] - pixels[i]));
  EXPECT_LT(worst, 1e-6);        // pixels
  EXPECT_LT(worst_angle, 1e-9);  // rad
}

TEST(RayPlane, PointsLieOnThePlaneAlongTheirRays) {
  const PinholeCamera camera = makeCamera(64, 48, true);
  const RayMap rays(camera);
  const Plane plane{{10.0, -4.0, 580.0}, testing::planeNormal(0.1, -0.15)};
  const cv::Mat xyz = intersectRaysWithPlane(rays, plane);
  ASSERT_EQ(xyz.type(), CV_32FC3);
  for (int v = 0; v < 48; ++v) {
    for (int u = 0; u < 64; ++u) {
      const cv::Vec3f p = xyz.at<cv::Vec3f>(v, u);
      const Eigen::Vector3d x(p[0], p[1], p[2]);
      EXPECT_NEAR(plane.signedDistance(x), 0.0, 1e-4);  // float storage of ~600 mm
      const Eigen::Vector3d own = pixelRay(camera, u, v);
      EXPECT_LT((x - x.norm() * own).norm(), 1e-4);
    }
  }
}

TEST(RayPlane, MaskParallelAndBehindGiveNaN) {
  const PinholeCamera camera = makeCamera(32, 24, false);
  const RayMap rays(camera);
  cv::Mat mask(24, 32, CV_8UC1, cv::Scalar(1));
  mask.at<std::uint8_t>(3, 4) = 0;
  const cv::Mat masked = intersectRaysWithPlane(rays, Plane{{0, 0, 600}, {0, 0, 1}}, mask);
  EXPECT_TRUE(std::isnan(masked.at<cv::Vec3f>(3, 4)[0]));
  EXPECT_FALSE(std::isnan(masked.at<cv::Vec3f>(3, 5)[0]));
  EXPECT_NEAR(masked.at<cv::Vec3f>(3, 5)[2], 600.0f, 1e-3);

  const cv::Mat behind = intersectRaysWithPlane(rays, Plane{{0, 0, -600}, {0, 0, 1}});
  EXPECT_EQ(countFinite(behind), 0);

  // A plane containing the optical axis: the pixel whose ray lies in it is NaN.
  const cv::Mat parallel = intersectRaysWithPlane(rays, Plane{{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(countFinite(parallel), 0);

  EXPECT_THROW(intersectRaysWithPlane(rays, Plane{{0, 0, 600}, {0, 0, 0}}), std::invalid_argument);
  EXPECT_THROW(intersectRaysWithPlane(rays, Plane{}, cv::Mat(3, 3, CV_8UC1)),
               std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::algo
