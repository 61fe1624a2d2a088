// SPDX-License-Identifier: Apache-2.0
// The reference-sphere check on synthetic clouds: the sphere is found beside
// a backdrop, its radius, RMSE and the VDI/VDE 2634-2 figures measured, and
// the pass decided by the tolerance.
#include "firmware/sphere_check.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace cylscan::firmware {
namespace {

// The front half of a sphere as a head sees it, with Gaussian radial noise,
// and a plane behind it.
formats::PointCloud sphereOnPlane(double radius, double noise_mm, std::uint32_t seed = 7) {
  formats::PointCloud cloud;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_mm);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double cz = 580;
  for (int i = 0; i < 20000; ++i) {
    // A direction on the half facing the camera (z < 0 from the centre).
    double x = unit(rng), y = unit(rng), z = -std::abs(unit(rng));
    const double n = std::sqrt(x * x + y * y + z * z);
    if (n < 1e-3 || n > 1) continue;
    const double r = radius + noise(rng);
    cloud.xyz.insert(cloud.xyz.end(), {static_cast<float>(r * x / n), static_cast<float>(r * y / n),
                                       static_cast<float>(cz + r * z / n)});
  }
  for (int i = 0; i < 20000; ++i) {
    cloud.xyz.insert(cloud.xyz.end(),
                     {static_cast<float>(150 * unit(rng)), static_cast<float>(150 * unit(rng)),
                      static_cast<float>(cz + radius + 2 + noise(rng))});
  }
  return cloud;
}

TEST(SphereCheck, MeasuresTheSphereBesideABackdrop) {
  SphereCheckOptions o;
  o.radius_mm = 50;
  o.tolerance_mm = 0.05;
  const SphereCheckResult r = checkSphere(sphereOnPlane(50.0, 0.02), o);
  ASSERT_TRUE(r.found) << r.reason;
  // ~15k points with 0.02 mm noise fix the radius far better than 0.005 mm;
  // float coordinates near 580 mm round at ~3e-5 mm.
  EXPECT_NEAR(r.measured_radius_mm, 50.0, 0.005);
  EXPECT_NEAR(r.rmse_mm, 0.02, 0.003);
  EXPECT_NEAR(r.probing_size_mm, 2 * (r.measured_radius_mm - 50.0), 1e-12);
  // Gaussian noise: the range of 99.7 % of the points is about 6σ.
  EXPECT_GT(r.probing_form_mm, 4 * 0.02);
  EXPECT_LT(r.probing_form_mm, 8 * 0.02);
  EXPECT_NEAR(r.centre_mm[2], 580.0, 0.01);
  EXPECT_GT(r.points, 10000u);
  EXPECT_LT(r.points, 20001u);  // the backdrop is not on the sphere
  EXPECT_TRUE(r.pass);
}

TEST(SphereCheck, ARadiusOffByMoreThanTheToleranceFails) {
  SphereCheckOptions o;
  o.radius_mm = 50;
  o.tolerance_mm = 0.05;
  // A head that scales by 0.4 %: the artifact measures 50.2 mm.
  const SphereCheckResult r = checkSphere(sphereOnPlane(50.2, 0.02), o);
  ASSERT_TRUE(r.found) << r.reason;
  EXPECT_NEAR(r.measured_radius_mm, 50.2, 0.005);
  EXPECT_NEAR(r.probing_size_mm, 0.4, 0.01);
  EXPECT_FALSE(r.pass);
}

TEST(SphereCheck, NoSphereOfThatRadiusIsNotFound) {
  SphereCheckOptions o;
  o.radius_mm = 20;
  o.tolerance_mm = 0.05;
  const SphereCheckResult r = checkSphere(sphereOnPlane(50.0, 0.02), o);
  EXPECT_FALSE(r.found);
  EXPECT_FALSE(r.pass);
  EXPECT_NE(r.reason.find("radius"), std::string::npos) << r.reason;
}

TEST(SphereCheck, RefusesANonPositiveRadiusOrTolerance) {
  SphereCheckOptions o;
  o.radius_mm = 0;
  o.tolerance_mm = 0.05;
  EXPECT_THROW(checkSphere({}, o), std::invalid_argument);
  o.radius_mm = 50;
  o.tolerance_mm = std::nan("");
  EXPECT_THROW(checkSphere({}, o), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::firmware
