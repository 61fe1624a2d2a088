// SPDX-License-Identifier: Apache-2.0
#include "algo/shift_weights.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "algo/fixed_weights.hpp"
#include "synthetic_fringes.hpp"

namespace cylscan::algo {
namespace {

using testing::kTwoPi;
using testing::stepGeometry;

TEST(ReproducibleCosSin, MatchesLibmToAboutOneUlp) {
  double worst = 0;
  for (int i = -2000; i <= 2000; ++i) {
    const double turns = i * 0.0123456789;
    const CosSin cs = reproducibleCosSinOfTurns(turns);
    // libm on the reduced argument (2π·turns itself would be rounded by ~1e-14).
    const double reduced = kTwoPi * (turns - std::floor(turns));
    worst = std::max(worst, std::abs(cs.cos - std::cos(reduced)));
    worst = std::max(worst, std::abs(cs.sin - std::sin(reduced)));
  }
  EXPECT_LT(worst, 2e-15);
  const CosSin quarter = reproducibleCosSinOfTurns(0.25);
  EXPECT_EQ(quarter.cos, 0.0);
  EXPECT_EQ(quarter.sin, 1.0);
}

TEST(ShiftWeights, EvenShiftsGiveThePapersEquation4) {
  const int n = 25;
  const ShiftWeights w(stepGeometry(5.0, n), "high");
  ASSERT_EQ(w.frameCount(), static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double delta = kTwoPi * k / n;
    EXPECT_NEAR(w.frame(k).a, 1.0 / n, 1e-14);
    EXPECT_NEAR(w.frame(k).c, 2.0 / n * std::cos(delta), 1e-14);
    EXPECT_NEAR(w.frame(k).s, 2.0 / n * std::sin(delta), 1e-14);
  }
  EXPECT_NEAR(w.conditionNumber(), 2.0, 1e-9);  // M = diag(N, N/2, N/2)
  EXPECT_NEAR(w.noiseGain(), 2.0 / n, 1e-14);
}

TEST(ShiftWeights, UnevenShiftsRecoverACSExactly) {
  // Quantised 0.225° steps and a partial period: the weights must still invert the model.
  for (const FringeSetGeometry& g :
       {stepGeometry(5.625, 25, 87.0, 1.0, 0.004), stepGeometry(5.0, 12, 3.0, 0.6, 0.004)}) {
    const ShiftWeights w(g, "low");
    const double a = 100, c = 37, s = -55;
    double ra = 0, rc = 0, rs = 0;
    for (std::size_t k = 0; k < w.frameCount(); ++k) {
      const double delta = kTwoPi * (g.stage_deg[k] - g.stage_deg[0]) / g.period_deg;
      const double intensity = a + c * std::cos(delta) + s * std::sin(delta);
      ra += w.frame(k).a * intensity;
      rc += w.frame(k).c * intensity;
      rs += w.frame(k).s * intensity;
    }
    EXPECT_NEAR(ra, a, 1e-9);
    EXPECT_NEAR(rc, c, 1e-9);
    EXPECT_NEAR(rs, s, 1e-9);
  }
}

TEST(ShiftWeights, PartialPeriodIsSolvedAndItsConditioningReported) {
  const ShiftWeights full(stepGeometry(5.0, 25), "high");
  const ShiftWeights partial(stepGeometry(5.0, 25, 0.0, 0.6), "high");
  std::printf("condition number: full period %.3f, 60 %% of a period %.3f\n",
              full.conditionNumber(), partial.conditionNumber());
  EXPECT_GT(partial.conditionNumber(), full.conditionNumber());
  EXPECT_LT(partial.conditionNumber(), ShiftWeights::kMaxConditionNumber);
  EXPECT_GT(partial.noiseGain(), full.noiseGain());
}

void expectSolveError(const FringeSetGeometry& g, const std::string& set,
                      const std::string& fragment) {
  try {
    const ShiftWeights w(g, set);
    FAIL() << "no exception for " << fragment;
  } catch (const ShiftSolveError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(set), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
  }
}

TEST(ShiftWeights, RejectsSingularSetsNamingTheSetAndTheFault) {
  expectSolveError({5.0, {0.0, 0.2}}, "high", "at least 3");
  expectSolveError({5.0, {1.0, 1.0, 1.0, 1.0}}, "low", "equal");
  // 0, half and a whole period: shifts 0, π, 2π ≡ 0 take 2 values mod 2π.
  expectSolveError({5.0, {0.0, 2.5, 5.0}}, "high", "2 distinct");
  expectSolveError({5.0, {0.0, 2.5, 5.0, 7.5}}, "low", "2 distinct");
  expectSolveError({5.0, {0.0, 1e-5, 2e-5, 3e-5}}, "high", "ill-conditioned");
  expectSolveError({0.0, {0.0, 1.0, 2.0}}, "low", "period");
  expectSolveError({5.0, {0.0, NAN, 2.0}}, "high", "stage_deg[1]");
  static_assert(std::is_base_of_v<std::invalid_argument, ShiftSolveError>);
}

TEST(FixedSetWeights, SumsAreExactAndTheBoundHolds) {
  for (int bits : {8, 12, 16}) {
    const int max_pixel = (1 << bits) - 1;
    const ShiftWeights high(testing::deviceHigh(), "high");
    const ShiftWeights low(testing::deviceLow(), "low");
    const ShiftWeights* sets[] = {&high, &low};
    const std::int64_t a_scale = FixedSetWeights::sharedTextureScale(sets, max_pixel);
    EXPECT_EQ(a_scale % 2, 0);
    std::int64_t texture_abs = 0;
    for (const ShiftWeights* w : sets) {
      const FixedSetWeights q = FixedSetWeights::quantize(*w, max_pixel, a_scale);
      std::int64_t sc = 0, ss = 0, sa = 0, abs_c = 0, abs_s = 0;
      for (std::size_t k = 0; k < q.frameCount(); ++k) {
        sc += q.c[k];
        ss += q.s[k];
        sa += q.a[k];
        abs_c += std::abs(q.c[k]);
        abs_s += std::abs(q.s[k]);
        texture_abs += std::abs(q.a[k]);
        EXPECT_EQ(q.a[k] % 2, 0);
        // Precision: each weight within one unit of the scaled real weight.
        EXPECT_LE(std::abs(q.c[k] - w->frame(k).c * q.cs_scale), 1.0);
      }
      EXPECT_EQ(sc, 0);
      EXPECT_EQ(ss, 0);
      EXPECT_EQ(sa, a_scale);
      EXPECT_LE(abs_c * max_pixel, FixedSetWeights::kSumLimit);
      EXPECT_LE(abs_s * max_pixel, FixedSetWeights::kSumLimit);
      // Maximal: doubling the scale would not fit.
      EXPECT_GT(2 * abs_c * max_pixel, FixedSetWeights::kSumLimit);
    }
    EXPECT_LT(texture_abs * max_pixel, FixedSetWeights::kSumLimit);
  }
}

TEST(RoundToSum, HitsTheTargetMovingTheLargestRemainders) {
  const double values[] = {0.4, 0.4, 0.4, -1.2};
  const auto r = roundToSum(values, 0);
  EXPECT_EQ(r[0] + r[1] + r[2] + r[3], 0);
  for (int i = 0; i < 4; ++i)
    EXPECT_LE(std::abs(r[i] - values[i]), 1.0);
}

}  // namespace
}  // namespace cylscan::algo
