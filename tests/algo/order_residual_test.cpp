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
  EXPECT_EQ(sa.reach, sb.reach);
  EXPECT_EQ(sa.near_antipode, sb.near_antipode);
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

// Residuals about `centre` whose error is bounded: the sum of two sinusoids
// of independent phases, a·sin(t1) + a·sin(t2) (the harmonics of the two sets
// multiplied by R and R − 1, densest at the centre), reaching ±2a, plus a
// little Gaussian noise and a fraction of outliers.
std::vector<std::int32_t> boundedAbout(double centre, double amplitude, double outliers,
                                       std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> turn(0.0, kTwoPi);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> anywhere(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<std::int32_t> out;
  for (std::size_t i = 0; i < n; ++i) {
    const double t1 = turn(rng), t2 = turn(rng);
    out.push_back(
        toUnits(unit(rng) < outliers
                    ? anywhere(rng)
                    : centre + amplitude / 2 * (std::sin(t1) + std::sin(t2)) + noise(rng)));
  }
  return out;
}

// A bounded error of ±2.3 rad has a MAD σ above 1 rad, for which the
// spread's rule falls to π/2 and would reject the fifth of the pixels beyond
// it, though none is near ±π and so none has a wrong order. The gap rule
// keeps them: halfway from the reach (a little under 2.3 rad) to π.
TEST(OrderResidual, ABoundedErrorThatLeavesTheAntipodeEmptyKeepsItsPixels) {
  std::vector<std::int32_t> r = boundedAbout(1.2, 2.3, 0.0, 8192, 23);
  const ResidualStatistics s = measureResiduals(r, kBits);
  EXPECT_EQ(s.near_antipode, 0u);
  // The sum's 99.9th percentile lies a little inside its reach of 2.3 rad.
  EXPECT_GT(toRad(s.reach), 2.0);
  EXPECT_LT(toRad(s.reach), 2.35);
  EXPECT_NEAR(toRad(residualBoundForSpread(s.spread, kBits)), std::numbers::pi / 2, 1e-6);
  const double bound = toRad(residualBound(s, kBits));
  EXPECT_NEAR(bound, (toRad(s.reach) + std::numbers::pi) / 2, 1e-6);
  EXPECT_GT(bound, 2.3);
  EXPECT_NEAR(toRad(s.centre), 1.2, 0.05);
}

// Where residuals reach ±π, some orders are wrong and look right: the gap
// rule stands aside and the spread's rule holds, for Gaussian noise of σ = 1
// and for a bounded error with 2 % of the pixels anywhere (8 times the
// outliers kAntipodeSamplesPerOutlier allows).
TEST(OrderResidual, ResidualsNearTheAntipodeKeepTheSpreadsBound) {
  std::vector<std::int32_t> gaussian = residualsAbout(0.4, 1.0, 0.0, 8192, 29);
  const ResidualStatistics g = measureResiduals(gaussian, kBits);
  EXPECT_GT(g.near_antipode, 8192u / kAntipodeSamplesPerOutlier);
  EXPECT_EQ(residualBound(g, kBits), residualBoundForSpread(g.spread, kBits));

  std::vector<std::int32_t> noisy = boundedAbout(-2.9, 2.3, 0.02, 8192, 31);
  const ResidualStatistics n = measureResiduals(noisy, kBits);
  EXPECT_GT(n.near_antipode, 8192u / kAntipodeSamplesPerOutlier);
  EXPECT_EQ(residualBound(n, kBits), residualBoundForSpread(n.spread, kBits));

  // A clean scan: the gap rule gives no less than the classic π/2.
  std::vector<std::int32_t> clean = residualsAbout(0.0, 0.02, 0.0, 8192, 37);
  const ResidualStatistics c = measureResiduals(clean, kBits);
  EXPECT_GE(toRad(residualBound(c, kBits)), std::numbers::pi / 2);
  EXPECT_LE(toRad(residualBound(c, kBits)), 0.9 * std::numbers::pi + 1e-6);
}

}  // namespace
}  // namespace cylscan::algo
