// SPDX-License-Identifier: Apache-2.0
#include "algo/sphere_search.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace cylscan::algo {
namespace {

// The visible cap (polar angle < 75° from the viewer at the origin) of a sphere,
// noise σ along the radius.
void addCap(Points3d& points, const Sphere& s, std::size_t n, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Vector3d towards = -s.centre.normalized();
  const double min_cos = std::cos(75.0 * std::numbers::pi / 180.0);
  for (std::size_t added = 0; added < n;) {
    const Eigen::Vector3d dir = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    if (dir.dot(towards) < min_cos) continue;
    points.push_back(s.centre + (s.radius + sigma * gauss(rng)) * dir);
    ++added;
  }
}

TEST(SphereSearch, FindsTheTargetsFourSpheresBeforeABackgroundPlane) {
  std::mt19937_64 rng(7);
  const std::vector<Sphere> truth = {{{-45.0, -30.0, 565.0}, 25.0},
                                     {{25.0, -18.0, 600.0}, 25.0},
                                     {{-5.0, 38.0, 585.0}, 25.0},
                                     {{32.0, 30.0, 548.0}, 25.0}};
  Points3d points;
  for (const Sphere& s : truth)
    addCap(points, s, 3000, 0.02, rng);
  // A plane behind them and scattered outliers.
  std::uniform_real_distribution<double> u(-120.0, 120.0);
  for (int i = 0; i < 8000; ++i)
    points.emplace_back(u(rng), u(rng), 660.0 + 0.02 * u(rng));
  for (int i = 0; i < 300; ++i)
    points.emplace_back(u(rng), u(rng), 580.0 + u(rng) / 4);

  SphereSearchOptions options;
  options.radius_mm = 25.0;
  const std::vector<FoundSphere> found = findSpheres(points, options);
  ASSERT_EQ(found.size(), 4u);
  for (const Sphere& s : truth) {
    const auto it = std::find_if(found.begin(), found.end(), [&](const FoundSphere& f) {
      return (f.fit.sphere.centre - s.centre).norm() < 1.0;
    });
    ASSERT_NE(it, found.end()) << s.centre.transpose();
    // 3000 points of σ = 0.02 mm on a cap: the centre to ~σ·few/√n ≈ 1e-3 mm.
    EXPECT_LT((it->fit.sphere.centre - s.centre).norm(), 0.01);
    EXPECT_NEAR(it->fit.sphere.radius, 25.0, 0.01);
    EXPECT_GT(it->inliers.size(), 2800u);  // nearly all of its 3000 points
  }
}

TEST(SphereSearch, AFreeRadiusSearchFindsASphereOfAnyRadius) {
  std::mt19937_64 rng(8);
  Points3d points;
  addCap(points, {{10.0, 5.0, 580.0}, 50.0}, 4000, 0.02, rng);
  SphereSearchOptions options;  // radius 0: any radius in [5, 200]
  const std::vector<FoundSphere> found = findSpheres(points, options);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_NEAR(found[0].fit.sphere.radius, 50.0, 0.01);
}

TEST(SphereSearch, APlaneAloneHoldsNoSphereOfTheKnownRadius) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  Points3d points;
  for (int i = 0; i < 5000; ++i)
    points.emplace_back(u(rng), u(rng), 600.0);
  SphereSearchOptions options;
  options.radius_mm = 25.0;
  EXPECT_TRUE(findSpheres(points, options).empty());
}

}  // namespace
}  // namespace cylscan::algo
