// SPDX-License-Identifier: Apache-2.0
#include "algo/order_residual.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace cylscan::algo {
namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;
constexpr int kBits = 27;  // the device's unit: R = 9, shift 11

double toRad(std::int64_t units) {
  return static_cast<double>(units) * kTwoPi / std::ldexp(1.0, kBits);
}
std::int32_t toUnits(double rad) {
  return wrapResidual(std::llround(rad / kTwoPi * std::ldexp(1.0, kBits)), kBits);
}

// Residuals about `centre` with Gaussian spread `sigma`, and a fraction of
// outliers anywhere on the circle (pixels at edges, in shadow).
std::vector<std::int32_t> residualsAbout(double centre, double sigma, double outliers,
                                         std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::uniform_real_distribution<double> anywhere(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<std::int32_t> out;
  for (std::size_t i = 0; i < n; ++i)
    out.push_back(toUnits(unit(rng) < outliers ? anywhere(rng) : centre + noise(rng)));
  return out;
}

// The offset between the sets may put the residuals' centre anywhere on the
// circle, across the ±π seam too; 30 % outliers do not move it.
TEST(OrderResidual, FindsTheCentreAnywhereOnTheCircle) {
  for (double centre : {0.0, 0.9, -1.53, 2.7, -3.1, 3.14}) {
    for (double sigma : {0.01, 0.1, 0.5}) {
      std::vector<std::int32_t> r = residualsAbout(centre, sigma, 0.3, 8000, 11);
      const ResidualStatistics s = measureResiduals(r, kBits);
      EXPECT_EQ(s.samples, 8000u);
      // The window's mean: 5600 inliers of σ sigma (fewer and narrower at
      // sigma = 0.5, where the window keeps ±1.6σ) and 600 outliers uniform
      // over ±π/4 (σ (π/4)/√3), symmetric about the centre once re-centred.
      // Its σ is √(5600·sigma² + 600·(π/4)²/3) / 6200; 6 of those.
      const double window_sigma =
          std::sqrt(5600 * sigma * sigma + 600 * std::pow(std::numbers::pi / 4, 2) / 3) / 6200;
      EXPECT_LT(std::abs(std::remainder(toRad(s.centre) - centre, kTwoPi)), 6 * window_sigma)
          << centre << " " << sigma;
    }
  }
}

// The spread is the residuals' σ. With 10 % of the pixels anywhere on the
// circle, the median of |r − centre| moves out: solving
// 0.9·P(|g| < m) + 0.1·m/π = 1/2 gives a spread of 1.13σ at σ → 0 and
// 1.11σ at σ = 0.5, so it lies within [σ, 1.2σ].
TEST(OrderResidual, SpreadIsTheNoise) {
  for (double sigma : {0.01, 0.1, 0.5}) {
    std::vector<std::int32_t> r = residualsAbout(-2.0, sigma, 0.1, 8000, 17);
    const double spread = toRad(measureResiduals(r, kBits).spread);
    EXPECT_GT(spread, 0.97 * sigma) << sigma;  // the median's own scatter: 2 %
    EXPECT_LT(spread, 1.2 * sigma) << sigma;
  }
}

TEST(OrderResidual, TooFewSamplesMeasureNothing) {
  std::vector<std::int32_t> r = residualsAbout(1.0, 0.1, 0.0, kMinResidualSamples - 1, 3);
  const ResidualStatistics s = measureResiduals(r, kBits);
  EXPECT_EQ(s.samples, kMinResidualSamples - 1);
  EXPECT_EQ(s.centre, 0);
  EXPECT_EQ(s.spread, 0);
}

// The same residuals give the same bits: integer arithmetic only.
TEST(OrderResidual, IsDeterministic) {
  std::vector<std::int32_t> a = residualsAbout(-2.0, 0.3, 0.2, 5000, 5);
  std::vector<std::int32_t> b = a;
  const ResidualStatistics sa = measureResiduals(a, kBits);
  const ResidualStatistics sb = measureResiduals(b, kBits);
  EXPECT_EQ(sa.centre, sb.centre);
  EXPECT_EQ(sa.spread, sb.spread);
}

TEST(OrderResidual, BoundFollowsTheSpread) {
  const auto bound = [](double sigma) {
    return toRad(residualBoundForSpread(toUnits(sigma), kBits));
  };
  constexpr double pi = std::numbers::pi;
  EXPECT_NEAR(bound(0.005), pi / 2, 1e-6);            // clean: the classic bound
  EXPECT_NEAR(bound(0.4), 6 * 0.4, 1e-6);             // 6σ
  EXPECT_NEAR(bound(0.55), 0.9 * pi, 1e-6);           // capped near ±π
  EXPECT_NEAR(bound(0.9), kTwoPi - 4.5 * 0.9, 1e-6);  // keeps 4.5σ to the next order
  EXPECT_NEAR(bound(2.0), pi / 2, 1e-6);              // hopeless: the floor
}

}  // namespace
}  // namespace cylscan::algo
