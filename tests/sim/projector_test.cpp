// SPDX-License-Identifier: Apache-2.0
// The cylindrical projector: slots, blur, conventions and imperfections.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "drivers/sim/projector.hpp"

namespace cylscan::sim {
namespace {

constexpr double kPi = std::numbers::pi;

ProjectorParams ideal() {
  ProjectorParams p;
  p.eccentricity_mm = 0;
  p.source_offset_mm = {0, 0, 0};
  return p;
}

// Fourier coefficient of T over one period centred at `centre` (cylinder deg).
double harmonic(const CylindricalProjector& proj, double centre, double period, int n,
                double* phase = nullptr) {
  const int samples = 2000;
  double c = 0, s = 0;
  for (int i = 0; i < samples; ++i) {
    const double b = centre - period / 2 + period * i / samples;
    const double a = 2 * kPi * n * b / period;
    c += proj.transmission(b) * std::cos(a);
    s += proj.transmission(b) * std::sin(a);
  }
  if (phase) *phase = std::atan2(s, c);
  return 2 * std::hypot(c, s) / samples;
}

TEST(Projector, SlotCountsAndPeriodsFollowThePaper) {
  const CylindricalProjector proj(ideal());
  int high = 0, low = 0;
  for (const auto& s : proj.slots())
    ((s[0] + s[1]) / 2 < 180 ? high : low) += 1;
  EXPECT_EQ(high, 36);  // 180 / 5
  EXPECT_EQ(low, 32);   // 180 / 5.625
  // Slot centres: m·θh and 180 + m·θl, duty 0.5.
  EXPECT_NEAR((proj.slots()[1][0] + proj.slots()[1][1]) / 2, 5.0, 1e-12);
  EXPECT_NEAR(proj.slots()[1][1] - proj.slots()[1][0], 2.5, 1e-12);
  EXPECT_NEAR((proj.slots()[37][0] + proj.slots()[37][1]) / 2, 185.625, 1e-12);
}

TEST(Projector, TableMatchesTheAnalyticBlurredSquareWave) {
  const CylindricalProjector proj(ideal());
  for (double b = 0; b < 360; b += 0.3717) {
    ASSERT_NEAR(proj.transmission(b), proj.transmissionExact(b), 2e-5) << b;
  }
  EXPECT_NEAR(proj.transmission(-1.0), proj.transmission(359.0), 1e-7);
}

TEST(Projector, FringesAreNearSinusoidalWithSmallHarmonics) {
  const CylindricalProjector proj(ideal());
  for (const auto& [centre, period] : {std::pair{90.0, 5.0}, std::pair{270.0, 5.625}}) {
    double phase = 0;
    const double mean = harmonic(proj, centre, period, 0) / 2;
    const double b1 = harmonic(proj, centre, period, 1, &phase);
    const double b2 = harmonic(proj, centre, period, 2);
    const double b3 = harmonic(proj, centre, period, 3);
    EXPECT_NEAR(mean, 0.5, 1e-3);
    EXPECT_GT(b1, 0.4);
    EXPECT_LT(b2 / b1, 1e-3);  // duty 0.5: no even harmonics
    EXPECT_GT(b3 / b1, 0.01);  // a few % of 3rd harmonic, as a real blurred slot
    EXPECT_LT(b3 / b1, 0.08);
    // Slot centres (full transmission) at β = m·θ on the high half and
    // 180° + m·θl on the low half: the fundamental has phase 0 there.
    EXPECT_NEAR(std::remainder(phase, 2 * kPi), 0.0, 1e-3) << centre;
  }
}

TEST(Projector, IdealWallAngleIsAzimuthMinusStageAngle) {
  const CylindricalProjector proj(ideal());
  const Vec3 x(-50, 20, 600);
  const double alpha = proj.azimuthDeg(x);
  for (double rho : {0.0, 12.3, 236.0, -40.0}) {
    EXPECT_NEAR(std::remainder(proj.wallAngleDeg(x, rho) - (alpha - rho), 360.0), 0.0, 1e-9);
  }
}

TEST(Projector, EccentricityAndSourceOffsetDistortWithDistance) {
  ProjectorParams p = ideal();
  p.eccentricity_mm = 0.5;
  p.source_offset_mm = {0.4, 0, -0.3};
  const CylindricalProjector proj(p);
  const CylindricalProjector ideal_proj(ideal());
  // Two points on one ray from the axis: the ideal projector gives them the
  // same wall angle, the imperfect one does not (distance-dependent distortion).
  const Vec3 axis(120, 0, 0), dir = Vec3(-0.2, 0.05, 1).normalized();
  const Vec3 near = axis + 540 * dir, far = axis + 620 * dir;
  EXPECT_NEAR(ideal_proj.wallAngleDeg(near, 10), ideal_proj.wallAngleDeg(far, 10), 1e-9);
  const double d = proj.wallAngleDeg(near, 10) - proj.wallAngleDeg(far, 10);
  EXPECT_GT(std::abs(d), 1e-4);
  // The eccentric offset rotates with the stage: the pattern shift is not
  // exactly the stage angle.
  const double s0 = proj.wallAngleDeg(near, 0), s1 = proj.wallAngleDeg(near, 90);
  EXPECT_GT(std::abs(std::remainder(s0 - s1 - 90.0, 360.0)), 1e-3);
}

TEST(Projector, FastPathEqualsTheExactIntersection) {
  ProjectorParams p;
  p.eccentricity_mm = 0.3;
  p.source_offset_mm = {0.2, 0.1, -0.4};
  const CylindricalProjector proj(p);
  for (const Vec3& x : {Vec3(-80, 30, 540), Vec3(60, -40, 620), Vec3(0, 0, 580)}) {
    const auto ray = proj.rayGeometry(x);
    for (double rho : {0.0, 33.3, 236.1, 56.2}) {
      EXPECT_NEAR(std::remainder(proj.wallAngleDeg(ray, rho) - proj.wallAngleDeg(x, rho), 360.0),
                  0.0, 2e-5);
    }
  }
}

TEST(Projector, VerticalExtentLimitsTheLight) {
  const CylindricalProjector proj(ideal());
  EXPECT_TRUE(proj.inVerticalExtent(Vec3(0, 0, 580)));
  EXPECT_FALSE(proj.inVerticalExtent(Vec3(0, -400, 580)));  // far above: beyond +25°
  EXPECT_FALSE(proj.inVerticalExtent(Vec3(0, 400, 580)));
}

TEST(Projector, ImpossibleParametersAreRejected) {
  ProjectorParams p;
  p.duty = 1.2;
  EXPECT_THROW(CylindricalProjector{p}, std::invalid_argument);
  p = ProjectorParams{};
  p.theta_low_deg = p.theta_high_deg;
  EXPECT_THROW(CylindricalProjector{p}, std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::sim
