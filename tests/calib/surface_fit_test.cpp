// SPDX-License-Identifier: Apache-2.0
#include "algo/surface_fit.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

namespace cylscan::algo {
namespace {

// Points on a tilted 160×120 mm plane at ~580 mm, noise σ along the normal.
Points3d noisyPlane(const Plane& plane, std::size_t n, double sigma, std::mt19937_64& rng) {
  const Eigen::Vector3d normal = plane.normal.normalized();
  const Eigen::Vector3d e1 = normal.unitOrthogonal();
  const Eigen::Vector3d e2 = normal.cross(e1);
  std::uniform_real_distribution<double> a(-80.0, 80.0), b(-60.0, 60.0);
  std::normal_distribution<double> noise(0.0, sigma);
  Points3d points;
  for (std::size_t i = 0; i < n; ++i)
    points.push_back(plane.point + a(rng) * e1 + b(rng) * e2 + noise(rng) * normal);
  return points;
}

// Points of the cap of a sphere seen from the origin (polar angle < 70°).
Points3d noisyCap(const Sphere& sphere, std::size_t n, double sigma, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Vector3d towards = -sphere.centre.normalized();
  const double max_polar = 70.0 * std::numbers::pi / 180.0;
  Points3d points;
  while (points.size() < n) {
    const Eigen::Vector3d d(unit(rng) * 2 - 1, unit(rng) * 2 - 1, unit(rng) * 2 - 1);
    if (d.norm() > 1.0 || d.norm() < 1e-3) continue;
    const Eigen::Vector3d dir = d.normalized();
    if (std::acos(dir.dot(towards)) > max_polar) continue;
    points.push_back(sphere.centre + (sphere.radius + noise(rng)) * dir);
  }
  return points;
}

double angleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized()))));
}

TEST(ResidualStats, MeanStdAndRmseAreConsistent) {
  const std::vector<double> r = {1.0, -1.0, 3.0, 1.0};
  const ResidualStats s = residualStats(r);
  EXPECT_DOUBLE_EQ(s.mean, 1.0);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(2.0));  // population STD
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(3.0));
  EXPECT_NEAR(s.rmse * s.rmse, s.mean * s.mean + s.std * s.std, 1e-12);
  EXPECT_EQ(s.count, 4u);
}

TEST(PlaneFit, RecoversAnExactPlane) {
  const Plane truth{{10.0, -5.0, 580.0}, Eigen::Vector3d(0.1, -0.2, 1.0).normalized()};
  std::mt19937_64 rng(1);
  const PlaneFit fit = fitPlane(noisyPlane(truth, 500, 0.0, rng));
  EXPECT_LT(angleBetween(fit.plane.normal, truth.normal), 1e-12);
  EXPECT_NEAR(truth.signedDistance(fit.plane.point), 0.0, 1e-10);
  EXPECT_LT(fit.rmse, 1e-10);
  EXPECT_GT(fit.plane.normal.z(), 0.0);
}

TEST(PlaneFit, RmseMatchesTheNoise) {
  const Plane truth{{0.0, 0.0, 600.0}, Eigen::Vector3d(-0.2, 0.1, 1.0).normalized()};
  std::mt19937_64 rng(2);
  const double sigma = 0.05;
  const std::size_t n = 20000;
  const PlaneFit fit = fitPlane(noisyPlane(truth, n, sigma, rng));
  // The RMSE of n residuals estimates σ with a relative SD of 1/√(2n) = 0.5 %.
  EXPECT_NEAR(fit.rmse, sigma, 4 * sigma / std::sqrt(2.0 * n));
  // Tilt error ~ σ/(extent·√n): ~1e-5 rad here.
  EXPECT_LT(angleBetween(fit.plane.normal, truth.normal), 1e-4);
}

TEST(PlaneFit, RejectsDegenerateInput) {
  const Points3d two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(fitPlane(two), std::invalid_argument);
  const Points3d line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_THROW(fitPlane(line), std::invalid_argument);
}

TEST(RobustPlaneFit, IgnoresTwentyPercentOutliers) {
  const Plane truth{{5.0, 2.0, 570.0}, Eigen::Vector3d(0.15, 0.05, 1.0).normalized()};
  std::mt19937_64 rng(3);
  const double sigma = 0.05;
  Points3d points = noisyPlane(truth, 8000, sigma, rng);
  std::uniform_real_distribution<double> off(-20.0, 20.0);
  for (std::size_t i = 0; i < points.size(); i += 5) {  // 20 %
    double d = off(rng);
    if (std::abs(d) < 1.0) d += d < 0 ? -1.0 : 1.0;  // make every outlier a real one
    points[i] += d * truth.normal;
  }
  const PlaneFit plain = fitPlane(points);
  const RobustPlaneFit robust = fitPlaneRobust(points);
  EXPECT_GT(plain.rmse, 3.0);                        // the outliers wreck the plain fit...
  EXPECT_NEAR(robust.fit.rmse, sigma, 0.1 * sigma);  // ...but not the robust one
  EXPECT_LT(angleBetween(robust.fit.plane.normal, truth.normal), 2e-4);
  EXPECT_NEAR(truth.signedDistance(robust.fit.plane.point), 0.0, 0.01);
  EXPECT_EQ(robust.inlier_count, 8000u * 4 / 5);
  for (std::size_t i = 0; i < points.size(); i += 5)
    EXPECT_EQ(robust.inliers[i], 0);

  const RobustPlaneFit again = fitPlaneRobust(points);  // deterministic for the seed
  EXPECT_EQ(again.inliers, robust.inliers);
  EXPECT_EQ(again.fit.plane.normal, robust.fit.plane.normal);
}

TEST(SphereFit, RecoversAnExactSphere) {
  const Sphere truth{{12.0, -8.0, 590.0}, 50.0};
  std::mt19937_64 rng(4);
  const SphereFit fit = fitSphere(noisyCap(truth, 2000, 0.0, rng));
  EXPECT_NEAR(fit.sphere.radius, 50.0, 1e-9);
  EXPECT_LT((fit.sphere.centre - truth.centre).norm(), 1e-8);
  EXPECT_LT(fit.rmse, 1e-9);
}

TEST(SphereFit, RadiusWithinTheStatisticalTolerance) {
  const Sphere truth{{-20.0, 10.0, 600.0}, 50.0};
  std::mt19937_64 rng(5);
  const double sigma = 0.1;
  const std::size_t n = 10000;
  const SphereFit fit = fitSphere(noisyCap(truth, n, sigma, rng));
  // On a 70° cap the radius and the centre's depth are correlated, which
  // inflates the radius SD over σ/√n (1e-3 mm) by a factor of a few; 10·σ/√n
  // is a > 3-sigma bound.
  EXPECT_NEAR(fit.sphere.radius, 50.0, 10 * sigma / std::sqrt(double(n)));
  EXPECT_NEAR(fit.rmse, sigma, 4 * sigma / std::sqrt(2.0 * n));
}

TEST(SphereFit, FixedRadiusGivesThePapersMetrics) {
  const Sphere truth{{0.0, 0.0, 580.0}, 50.0};
  std::mt19937_64 rng(6);
  const double sigma = 0.1;
  const Points3d points = noisyCap(truth, 10000, sigma, rng);
  const FixedRadiusSphereFit fit = fitSphereFixedRadius(points, 50.0);
  EXPECT_LT((fit.sphere.centre - truth.centre).norm(), 0.01);
  EXPECT_NEAR(fit.residuals.rmse, sigma, 0.005);
  EXPECT_NEAR(fit.residuals.std, sigma, 0.005);
  EXPECT_NEAR(fit.residuals.mean, 0.0, 0.005);
  EXPECT_EQ(fit.residuals.count, points.size());

  // A reference radius 0.2 mm smaller than the artifact: positive bias, and
  // RMSE² = mean² + STD² holds exactly.
  const FixedRadiusSphereFit small = fitSphereFixedRadius(points, 49.8);
  EXPECT_GT(small.residuals.mean, 0.0);
  EXPECT_NEAR(
      small.residuals.rmse * small.residuals.rmse,
      small.residuals.mean * small.residuals.mean + small.residuals.std * small.residuals.std,
      1e-12);
}

TEST(SphereFit, RejectsDegenerateInput) {
  const Points3d coplanar = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 1, 0}};
  EXPECT_THROW(fitSphere(coplanar), std::invalid_argument);
  EXPECT_THROW(fitSphereFixedRadius(coplanar, 0.0), std::invalid_argument);
}

TEST(RegionalRmse, SplitsCentralAndOuterBands) {
  // u over [0, 99]: central |u − 49.5| ≤ 14.85, outer u ≤ 14.85 or u ≥ 84.15.
  std::vector<double> u, r;
  for (int i = 0; i < 100; ++i) {
    u.push_back(i);
    const bool central = std::abs(i - 49.5) <= 14.85;
    const bool outer = i <= 14.85 || i >= 84.15;
    r.push_back(central ? 1.0 : outer ? (i % 2 ? 2.0 : -2.0) : 100.0);
  }
  const RegionalRmse out = regionalRmse(r, u, 0.0, 99.0);
  EXPECT_DOUBLE_EQ(out.central, 1.0);
  EXPECT_DOUBLE_EQ(out.outer, 2.0);
  EXPECT_EQ(out.central_count, 30u);
  EXPECT_EQ(out.outer_count, 30u);
}

TEST(PointExtraction, SkipsNonFinitePoints) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> xyz = {1, 2, 3, nan, 0, 0, 4, 5, 6};
  EXPECT_EQ(pointsFromXyz(xyz).size(), 2u);
  cv::Mat map(2, 2, CV_32FC3, cv::Scalar(1, 2, 3));
  map.at<cv::Vec3f>(1, 0)[2] = nan;
  EXPECT_EQ(pointsFromXyzMap(map).size(), 3u);
}

}  // namespace
}  // namespace cylscan::algo
