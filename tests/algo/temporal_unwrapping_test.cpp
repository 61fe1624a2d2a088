// SPDX-License-Identifier: Apache-2.0
#include "algo/temporal_unwrapping.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace cylscan::algo {
namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;

BinaryAngle toBinary(double rad) {
  return static_cast<BinaryAngle>(std::lround(rad / kTwoPi * 65536.0) & 0xFFFF);
}

TEST(TwoWavelengthUnwrapper, RatiosAreExactForTheDevicePeriods) {
  const TwoWavelengthUnwrapper u(5.0, 5.625);
  EXPECT_EQ(u.ratioHigh(), 9.0);
  EXPECT_EQ(u.ratioLow(), 8.0);
  EXPECT_TRUE(u.ratioIsInteger());
  EXPECT_EQ(u.ordersHigh(), 9);
  EXPECT_EQ(u.ordersLow(), 8);
  EXPECT_EQ(u.equivalentPeriodDeg(), 45.0);
  // The fixed multiplier is R exactly.
  EXPECT_EQ(u.fixedParams().ratio_q, 9 << u.fixedParams().shift);
}

// Every Φ over the equivalent period: both forms recover K (and the low order).
void checkAllOrders(double period_high, double period_low) {
  const TwoWavelengthUnwrapper u(period_high, period_low);
  const double rho = period_low / period_high;
  const double range = kTwoPi * u.ratioHigh();
  int checked = 0;
  for (int i = 0; i < 20000; ++i) {
    const double truth = (i + 0.5) / 20000 * range;
    const double phi_h = std::fmod(truth, kTwoPi);
    const double phi_l = std::fmod(truth / rho, kTwoPi);
    const int k = static_cast<int>(std::floor(truth / kTwoPi));
    const int kl = static_cast<int>(std::floor(truth / rho / kTwoPi));
    // Stay clear of the wrap of either phase, where binary rounding moves it across.
    if (phi_h < 1e-3 || phi_h > kTwoPi - 1e-3 || phi_l < 1e-3 || phi_l > kTwoPi - 1e-3) continue;
    const ReferenceOrders r = u.unwrap(phi_h, phi_l);
    ASSERT_EQ(r.high, k) << truth;
    ASSERT_EQ(r.low, kl) << truth;
    ASSERT_NEAR(r.residual_rad, 0, 1e-9);
    const FixedOrders f = u.unwrap(toBinary(phi_h), toBinary(phi_l));
    ASSERT_EQ(f.high, k) << truth;
    ASSERT_EQ(f.low, kl) << truth;
    ASSERT_LT(std::abs(u.fixedResidualToRadians(f.residual)), 20 * kTwoPi / 65536);
    ++checked;
  }
  EXPECT_GT(checked, 15000);
}

TEST(TwoWavelengthUnwrapper, RecoversEveryOrderDevicePeriods) {
  checkAllOrders(5.0, 5.625);
}
TEST(TwoWavelengthUnwrapper, RecoversEveryOrderOtherPeriods) {
  checkAllOrders(4.0, 5.0);   // R = 5
  checkAllOrders(3.0, 3.25);  // R = 13
}

TEST(TwoWavelengthUnwrapper, ResidualMeasuresOrderInconsistency) {
  const TwoWavelengthUnwrapper u(5.0, 5.625);
  // Corrupt φl by e: the residual moves by R·(−e) wrapped to [-π, π).
  const double truth = 20.0, e = 0.25;
  const double phi_h = std::fmod(truth, kTwoPi);
  const double phi_l = std::fmod(truth / 1.125 + e, kTwoPi);
  const double expected = std::remainder(-9 * e, kTwoPi);
  EXPECT_NEAR(u.unwrap(phi_h, phi_l).residual_rad, expected, 1e-9);
  const FixedOrders f = u.unwrap(toBinary(phi_h), toBinary(phi_l));
  EXPECT_NEAR(u.fixedResidualToRadians(f.residual), expected, 1e-3);
  EXPECT_NEAR(u.fixedResidualToRadians(u.fixedResidualBound(1.0)), 1.0, 1e-6);
}

// A centre taken near a calibration's may lie up to a whole turn from zero:
// the integer form must still agree with the reference on every order, for
// ratios from just above 2 (two orders, one low order) up to the device's.
TEST(TwoWavelengthUnwrapper, CentresUpToATurnAwayAgreeWithTheReference) {
  for (const auto& [high, low] : {std::pair{5.0, 5.625}, {3.0, 3.25}, {4.0, 7.0}, {2.0, 3.9}}) {
    TwoWavelengthUnwrapper u(high, low);
    FixedUnwrapParams p = u.fixedParams();
    const int bits = 16 + p.shift;
    // ratio_q is R rounded to 2^-shift (exact for the device's R = 9): over
    // φeq < 2π that moves the residual by less than π·2^-shift.
    const double tolerance = std::numbers::pi * std::ldexp(1.0, -p.shift) + 1e-9;
    int checked = 0;
    for (int c = -16; c < 16; ++c) {
      p.residual_centre = static_cast<std::int32_t>(std::ldexp(c / 16.0, bits));
      const double centre_rad = c / 16.0 * kTwoPi;
      for (int i = 0; i < 4000; ++i) {
        const double phi_h = (i * 0.7548776662 - std::floor(i * 0.7548776662)) * kTwoPi;
        const double phi_l = (i * 0.5698402910 - std::floor(i * 0.5698402910)) * kTwoPi;
        const BinaryAngle bh = toBinary(phi_h), bl = toBinary(phi_l);
        const ReferenceOrders r =
            u.unwrap(bh * kTwoPi / 65536.0, bl * kTwoPi / 65536.0, centre_rad);
        // Near ±π the two forms may round to different neighbours: skip those.
        if (std::abs(std::abs(r.residual_rad) - std::numbers::pi) < tolerance) continue;
        const FixedOrders f = unwrapFixed(p, bh, bl);
        ASSERT_EQ(f.high, r.high) << high << "/" << low << " centre " << c << "/16 turn, " << i;
        ASSERT_EQ(f.low, r.low) << high << "/" << low << " centre " << c << "/16 turn, " << i;
        ASSERT_GE(f.high, 0);
        ASSERT_LT(f.high, u.ordersHigh());
        ASSERT_GE(f.low, 0);
        ASSERT_LT(f.low, u.ordersLow());
        ASSERT_NEAR(u.fixedResidualToRadians(f.residual), r.residual_rad, tolerance);
        ++checked;
      }
    }
    EXPECT_GT(checked, 32 * 3900);
  }
}

TEST(TwoWavelengthUnwrapper, RejectsBadPeriods) {
  EXPECT_THROW(TwoWavelengthUnwrapper(5.625, 5.0), std::invalid_argument);
  EXPECT_THROW(TwoWavelengthUnwrapper(5.0, 5.0), std::invalid_argument);
  EXPECT_THROW(TwoWavelengthUnwrapper(0.0, 5.0), std::invalid_argument);
  EXPECT_THROW(TwoWavelengthUnwrapper(5.0, 5.01), std::invalid_argument);  // R = 501
}

}  // namespace
}  // namespace cylscan::algo
