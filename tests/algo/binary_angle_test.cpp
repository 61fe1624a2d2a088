// SPDX-License-Identifier: Apache-2.0
#include "algo/binary_angle.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace cylscan::algo {
namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;
constexpr double kLsb = kTwoPi / 65536;

double wrappedError(BinaryAngle a, double exact) {
  double d = std::fmod(binaryAngleToRadians(a) - exact, kTwoPi);
  if (d < -std::numbers::pi) d += kTwoPi;
  if (d >= std::numbers::pi) d -= kTwoPi;
  return d;
}

TEST(BinaryAngle, OctantPolynomialIsExactToAFractionOfAnLsbForEveryInput) {
  // Every Q16 fraction of the octant, and the floats just below and above each,
  // so that the end points and any t a division can give are near a tested one.
  double worst = 0;
  for (std::uint32_t q = 0; q <= 65536; ++q) {
    const float centre = static_cast<float>(q) / 65536.0f;
    // nextafter stays within [0, 1] at both ends.
    for (const float t : {std::nextafter(centre, 0.0f), centre, std::nextafter(centre, 1.0f)}) {
      const double exact = std::atan(static_cast<double>(t)) / kTwoPi * 524288.0;  // 2^-19 turn
      worst = std::max(worst, std::abs(octantAtan(t) - exact));
    }
  }
  std::printf("octant polynomial: max error %.3f LSB of 2^-16 turn\n", worst / 8);
  EXPECT_LT(worst / 8, 0.5);
  EXPECT_EQ(octantAtan(0.0f), 0u);
  EXPECT_EQ(octantAtan(1.0f), 65536u);  // the diagonal: exactly an eighth of a turn
}

TEST(BinaryAngle, Atan2MatchesStdAtan2WithinOneLsb) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> angle(0, kTwoPi);
  std::uniform_real_distribution<double> log_radius(0, std::log(1.5e9));
  double worst = 0, sum_sq = 0;
  const int samples = 400000;
  for (int i = 0; i < samples; ++i) {
    const double r = std::exp(log_radius(rng)) + 30;
    const double a = angle(rng);
    const auto c = static_cast<std::int32_t>(std::lround(r * std::cos(a)));
    const auto s = static_cast<std::int32_t>(std::lround(r * std::sin(a)));
    const double e = wrappedError(binaryAtan2(s, c), std::atan2(s, c));
    worst = std::max(worst, std::abs(e));
    sum_sq += e * e;
  }
  std::printf("binaryAtan2: max error %.3e rad (%.2f LSB), rms %.3e rad\n", worst, worst / kLsb,
              std::sqrt(sum_sq / samples));
  EXPECT_LT(worst, 1.0 * kLsb);
}

TEST(BinaryAngle, AxesDiagonalsAndExtremes) {
  EXPECT_EQ(binaryAtan2(0, 0), 0);
  EXPECT_EQ(binaryAtan2(0, 5), 0);
  EXPECT_EQ(binaryAtan2(5, 0), 16384);
  EXPECT_EQ(binaryAtan2(0, -5), 32768);
  EXPECT_EQ(binaryAtan2(-5, 0), 49152);
  EXPECT_EQ(binaryAtan2(7, 7), 8192);
  EXPECT_EQ(binaryAtan2(-7, -7), 40960);
  const std::int32_t big = 2147483647;
  EXPECT_EQ(binaryAtan2(big, big), 8192);
  EXPECT_EQ(binaryAtan2(-big, 0), 49152);
  EXPECT_LE(std::abs(wrappedError(binaryAtan2(-1, big), std::atan2(-1.0, big))), kLsb);
}

TEST(BinaryAngle, WrapsFreelyAsUint16) {
  const BinaryAngle a = 65000, b = 1000;
  EXPECT_EQ(static_cast<BinaryAngle>(b - a), 1536);
  EXPECT_NEAR(binaryAngleToRadians(static_cast<BinaryAngle>(b - a)), 1536 * kLsb, 1e-15);
}

}  // namespace
}  // namespace cylscan::algo
