// SPDX-License-Identifier: Apache-2.0
#include "algo/phase_engine.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "algo/fixed_kernels.hpp"
#include "algo/order_residual.hpp"
#include "synthetic_fringes.hpp"

namespace cylscan::algo {
namespace {

using testing::angleDifference;
using testing::deviceHigh;
using testing::deviceLow;
using testing::kTwoPi;
using testing::runScan;
using testing::Scene;
using testing::stepGeometry;

// Most tests run on small images, to keep the suite fast.
cv::Size smallSize() {
  return {128, 96};
}

PhaseOptions fixedOptions(int bits = 8) {
  PhaseOptions o;
  o.bit_depth = bits;
  return o;
}
PhaseOptions referenceOptions(int bits = 8) {
  PhaseOptions o = fixedOptions(bits);
  o.fixed_point = false;
  return o;
}

struct ErrorStats {
  double rms = 0, worst = 0;
  int count = 0;
};

// Wrapped phase of `set` against the truth, over valid pixels of `maps`.
ErrorStats wrappedError(const PhaseMaps& maps, const Scene& scene, FringeSet set) {
  const cv::Mat& wrapped = set == FringeSet::High ? maps.wrapped_high : maps.wrapped_low;
  const double scale = set == FringeSet::High ? 1.0 : testing::kHighPeriod / testing::kLowPeriod;
  ErrorStats s;
  double sum = 0;
  for (int y = 0; y < wrapped.rows; ++y) {
    for (int x = 0; x < wrapped.cols; ++x) {
      if (maps.invalid.at<std::uint8_t>(y, x) != 0) continue;
      const double e =
          angleDifference(wrapped.at<float>(y, x), scene.absolute_high.at<double>(y, x) * scale);
      sum += e * e;
      s.worst = std::max(s.worst, std::abs(e));
      ++s.count;
    }
  }
  s.rms = s.count > 0 ? std::sqrt(sum / s.count) : 0;
  return s;
}

// An absolute map (Φ or the fused Φ) against the truth, over valid pixels.
ErrorStats absoluteError(const cv::Mat& absolute, const PhaseMaps& maps, const Scene& scene) {
  ErrorStats s;
  double sum = 0;
  for (int y = 0; y < absolute.rows; ++y) {
    for (int x = 0; x < absolute.cols; ++x) {
      if (maps.invalid.at<std::uint8_t>(y, x) != 0) continue;
      const double e = absolute.at<float>(y, x) - scene.absolute_high.at<double>(y, x);
      sum += e * e;
      s.worst = std::max(s.worst, std::abs(e));
      ++s.count;
    }
  }
  s.rms = s.count > 0 ? std::sqrt(sum / s.count) : 0;
  return s;
}

bool bitIdentical(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y) {
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  }
  return true;
}

void expectIdenticalMaps(const PhaseMaps& a, const PhaseMaps& b) {
  EXPECT_TRUE(bitIdentical(a.wrapped_high, b.wrapped_high));
  EXPECT_TRUE(bitIdentical(a.wrapped_low, b.wrapped_low));
  EXPECT_TRUE(bitIdentical(a.modulation_high, b.modulation_high));
  EXPECT_TRUE(bitIdentical(a.modulation_low, b.modulation_low));
  EXPECT_TRUE(bitIdentical(a.texture, b.texture));
  EXPECT_TRUE(bitIdentical(a.fringe_order, b.fringe_order));
  EXPECT_TRUE(bitIdentical(a.absolute, b.absolute));
  EXPECT_TRUE(bitIdentical(a.fused, b.fused));
  EXPECT_TRUE(bitIdentical(a.invalid, b.invalid));
  EXPECT_EQ(a.valid_fraction, b.valid_fraction);
}

int expectedOrder(double truth) {
  return static_cast<int>(std::floor(truth / kTwoPi));
}

// ---- phase recovery ----------------------------------------------------------

struct GeometryCase {
  const char* name;
  FringeSetGeometry high, low;
};

TEST(PhaseEngine, RecoversPhaseForEvenQuantisedAndPartialShifts) {
  const GeometryCase cases[] = {
      {"even", stepGeometry(5.0, 25), stepGeometry(5.625, 25)},
      {"quantised 0.004 deg steps", deviceHigh(), deviceLow()},
      {"60 % of a period", stepGeometry(5.0, 25, -90, 0.6, 0.004),
       stepGeometry(5.625, 25, 87, 0.6, 0.004)},
      {"uneven N (12 and 7 frames)", stepGeometry(5.0, 12, 0, 1.0, 0.004),
       stepGeometry(5.625, 7, 0, 1.0, 0.004)},
  };
  const Scene scene = testing::rampScene(smallSize(), 120, 90);
  for (const GeometryCase& c : cases) {
    PhaseEngine engine(smallSize(), c.high, c.low, fixedOptions());
    const double gain = engine.noiseGain(FringeSet::High);
    // Rounding to integers is noise of 1/sqrt(12) counts: σφ = σ·sqrt(gain)/B.
    const double expected_rms = std::sqrt(1.0 / 12) * std::sqrt(gain) / 90;
    for (bool fixed : {true, false}) {
      const PhaseMaps maps =
          runScan(scene, c.high, c.low, fixed ? fixedOptions() : referenceOptions());
      const ErrorStats e = wrappedError(maps, scene, FringeSet::High);
      const ErrorStats a = absoluteError(maps.absolute, maps, scene);
      std::printf(
          "%-28s %-9s cond %.2f/%.2f  wrapped rms %.2e (theory %.2e) max %.2e  valid %.4f\n",
          c.name, fixed ? "fixed" : "reference", engine.conditionNumber(FringeSet::High),
          engine.conditionNumber(FringeSet::Low), e.rms, expected_rms, e.worst,
          maps.valid_fraction);
      EXPECT_EQ(maps.valid_fraction, 1.0) << c.name;
      EXPECT_LT(e.rms, 1.5 * expected_rms + 1e-4) << c.name;
      EXPECT_LT(a.worst, 8 * expected_rms + 5e-4) << c.name;  // no order is wrong anywhere
    }
  }
}

TEST(PhaseEngine, BitDepths8And12And16) {
  for (int bits : {8, 12, 16}) {
    const double full = (1 << bits) - 1;
    const Scene scene = testing::rampScene(smallSize(), 0.45 * full, 0.35 * full);
    for (bool fixed : {true, false}) {
      PhaseOptions o = fixed ? fixedOptions(bits) : referenceOptions(bits);
      const PhaseMaps maps = runScan(scene, deviceHigh(), deviceLow(), o);
      const ErrorStats e = wrappedError(maps, scene, FringeSet::High);
      const ErrorStats el = wrappedError(maps, scene, FringeSet::Low);
      // Rounding noise only: σφ = 0.29·sqrt(2/25)/B, plus the fixed-point floor: the
      // binary angle (LSB/sqrt(12) = 2.8e-5), the atan polynomial (< 0.5 LSB) and, at 16
      // bits, the weight quantisation (1/cs_scale ≈ 4e-5 rad): about 5e-5 rad RMS.
      const double expected = std::sqrt(1.0 / 12) * std::sqrt(2.0 / 25) / (0.35 * full);
      EXPECT_EQ(maps.valid_fraction, 1.0);
      EXPECT_LT(e.rms, 1.5 * expected + 8e-5) << bits << (fixed ? " fixed" : " reference");
      EXPECT_LT(el.rms, 1.5 * expected + 8e-5) << bits << (fixed ? " fixed" : " reference");
      // Modulation and texture in counts.
      EXPECT_NEAR(cv::mean(maps.modulation_high)[0], 0.35 * full, 0.002 * full + 0.1);
      EXPECT_NEAR(cv::mean(maps.modulation_low)[0], 0.35 * full, 0.002 * full + 0.1);
      EXPECT_NEAR(cv::mean(maps.texture)[0], 0.45 * full, 0.002 * full + 0.1);
    }
  }
}

TEST(PhaseEngine, PhaseNoiseFollowsTheory) {
  // σφ ≈ σI·sqrt(2/N)/B for N even shifts.
  const double a = 30000, b = 20000, sigma = 300;
  const Scene scene = testing::rampScene(smallSize(), a, b);
  const double theory = sigma * std::sqrt(2.0 / 25) / b;
  for (bool fixed : {true, false}) {
    const PhaseMaps maps = runScan(scene, stepGeometry(5.0, 25), stepGeometry(5.625, 25),
                                   fixed ? fixedOptions(16) : referenceOptions(16), sigma, 3);
    const ErrorStats e = wrappedError(maps, scene, FringeSet::High);
    std::printf("%s: phase noise %.3e rad, theory %.3e (ratio %.3f)\n",
                fixed ? "fixed" : "reference", e.rms, theory, e.rms / theory);
    // 12288 samples: the RMS estimate is good to about 1 %.
    EXPECT_NEAR(e.rms / theory, 1.0, 0.06);
  }
}

// ---- agreement of the two paths ------------------------------------------------

TEST(PhaseEngine, FixedPointAgreesWithDoubleReference) {
  const Scene scene = testing::rampScene(smallSize(), 110, 70);
  double worst = 0, sum = 0;
  int count = 0, order_mismatch = 0, flag_mismatch = 0;
  for (int seed : {1, 2}) {
    const PhaseMaps fixed = runScan(scene, deviceHigh(), deviceLow(), fixedOptions(), 1.5, seed);
    const PhaseMaps ref = runScan(scene, deviceHigh(), deviceLow(), referenceOptions(), 1.5, seed);
    for (int y = 0; y < smallSize().height; ++y) {
      for (int x = 0; x < smallSize().width; ++x) {
        const bool ref_valid = ref.invalid.at<std::uint8_t>(y, x) == 0;
        flag_mismatch += ref.invalid.at<std::uint8_t>(y, x) != fixed.invalid.at<std::uint8_t>(y, x);
        if (!ref_valid) continue;
        for (const cv::Mat PhaseMaps::*m : {&PhaseMaps::wrapped_high, &PhaseMaps::wrapped_low}) {
          const double e = angleDifference((fixed.*m).at<float>(y, x), (ref.*m).at<float>(y, x));
          worst = std::max(worst, std::abs(e));
          sum += e * e;
          ++count;
        }
        order_mismatch +=
            fixed.fringe_order.at<std::int16_t>(y, x) != ref.fringe_order.at<std::int16_t>(y, x);
      }
    }
  }
  const double rms = std::sqrt(sum / count);
  std::printf(
      "fixed vs double: wrapped rms %.3e rad, max %.3e rad over %d phases; %d order "
      "mismatches; %d flag mismatches\n",
      rms, worst, count, order_mismatch, flag_mismatch);
  EXPECT_LT(rms, 1e-3);
  EXPECT_LT(worst, 4e-3);
  EXPECT_EQ(order_mismatch, 0);
  EXPECT_LE(flag_mismatch, count / 1000);
}

// ---- fringe orders with isolated objects ----------------------------------------

TEST(PhaseEngine, LargeDepthStepsGetTheRightOrderAtEveryPixel) {
  // 4x4-pixel blocks with independent random Φ over all 9 orders: steps of several
  // periods between neighbouring pixels, as at the edges of isolated objects.
  Scene scene = testing::uniformScene(smallSize(), 110, 90);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> phase(0.02, 9 * kTwoPi - 0.02);
  for (int y = 0; y < smallSize().height; y += 4) {
    for (int x = 0; x < smallSize().width; x += 4) {
      scene.absolute_high(cv::Rect(x, y, 4, 4)).setTo(phase(rng));
    }
  }
  double biggest_step = 0;
  std::vector<int> seen(9, 0);
  for (int y = 0; y < smallSize().height; ++y) {
    for (int x = 1; x < smallSize().width; ++x) {
      biggest_step = std::max(biggest_step, std::abs(scene.absolute_high.at<double>(y, x) -
                                                     scene.absolute_high.at<double>(y, x - 1)));
      ++seen[expectedOrder(scene.absolute_high.at<double>(y, x))];
    }
  }
  ASSERT_GT(biggest_step, 6 * kTwoPi);
  for (int k = 0; k < 9; ++k)
    ASSERT_GT(seen[k], 0) << k;

  for (bool fixed : {true, false}) {
    const PhaseMaps maps = runScan(scene, deviceHigh(), deviceLow(),
                                   fixed ? fixedOptions() : referenceOptions(), 0.7, 9);
    int wrong = 0;
    for (int y = 0; y < smallSize().height; ++y) {
      for (int x = 0; x < smallSize().width; ++x) {
        const double truth = scene.absolute_high.at<double>(y, x);
        ASSERT_EQ(maps.invalid.at<std::uint8_t>(y, x), 0) << x << "," << y;
        const double err = maps.absolute.at<float>(y, x) - truth;
        wrong += std::abs(err) > 0.05;
        const double to_edge = std::abs(std::remainder(truth, kTwoPi));
        if (to_edge > 0.05) {
          wrong += maps.fringe_order.at<std::int16_t>(y, x) != expectedOrder(truth);
        }
      }
    }
    EXPECT_EQ(wrong, 0) << (fixed ? "fixed" : "reference");
  }
}

// ---- validity flags ---------------------------------------------------------------

TEST(PhaseEngine, FlagsLowModulationSaturationAndInconsistentOrders) {
  // Columns: [0,32) dark (B = 2 < 5.1), [32,48) low phase corrupted by 0.3 rad
  // (residual 9·0.3 = 2.7 rad, far beyond the spread of the rest), [48,64)
  // fine, [64,96) saturated (A + B = 300), [96,128) fine. The fine pixels are
  // the majority of the modulated ones, so the residuals' centre is theirs.
  Scene scene = testing::rampScene(smallSize(), 110, 80);
  scene.modulation.colRange(0, 32).setTo(2.0);
  scene.low_offset = cv::Mat::zeros(smallSize(), CV_64F);
  scene.low_offset.colRange(32, 48).setTo(0.3);
  scene.background.colRange(64, 96).setTo(200.0);
  scene.modulation.colRange(64, 96).setTo(100.0);
  for (bool fixed : {true, false}) {
    const PhaseMaps maps =
        runScan(scene, deviceHigh(), deviceLow(), fixed ? fixedOptions() : referenceOptions(), 0.5);
    for (int y = 0; y < smallSize().height; ++y) {
      for (int x = 0; x < smallSize().width; ++x) {
        const std::uint8_t flags = maps.invalid.at<std::uint8_t>(y, x);
        const int region = x >= 32 && x < 48 ? 1 : x >= 48 && x < 64 ? 3 : x / 32;
        if (region == 0) {
          ASSERT_TRUE(flags & kLowModulation) << x << "," << y;
        }
        if (region == 1) {
          ASSERT_EQ(flags, kOrderInconsistent) << x << "," << y;
        }
        if (region == 2) {
          ASSERT_TRUE(flags & kSaturated) << x << "," << y;
        }
        if (region == 3) {
          ASSERT_EQ(flags, kValid) << x << "," << y;
        }
        if (region != 0) {
          ASSERT_FALSE(flags & kLowModulation) << x << "," << y;
        }
        if (region != 2) {
          ASSERT_FALSE(flags & kSaturated) << x << "," << y;
        }
        ASSERT_EQ(std::isnan(maps.absolute.at<float>(y, x)), flags != 0);
        ASSERT_EQ(std::isnan(maps.fused.at<float>(y, x)), flags != 0);
      }
    }
    EXPECT_NEAR(maps.valid_fraction, 48.0 / 128, 1e-12);
    EXPECT_NEAR(maps.order_residual.centre_rad, 0, 0.01);
    EXPECT_NEAR(maps.order_residual.bound_rad, std::numbers::pi / 2, 1e-6);
  }
}

// Any constant phase offset of the low set (a misaligned slot half, a start
// angle off by a fraction of a degree) moves every residual by −R·δ. The
// engine finds that centre and unwraps around it: the same pixels stay valid,
// and every order moves by one constant (mod 9), so Φ keeps its shape.
TEST(PhaseEngine, AnyOffsetBetweenTheSetsUnwrapsTheSame) {
  const Scene clean = testing::rampScene(smallSize(), 110, 80);
  for (bool fixed : {true, false}) {
    const PhaseOptions o = fixed ? fixedOptions() : referenceOptions();
    const PhaseMaps ref = runScan(clean, deviceHigh(), deviceLow(), o, 0.5);
    ASSERT_EQ(ref.valid_fraction, 1.0);
    for (double delta : {0.1, 0.17, 0.3, -0.25, 0.6, 0.349}) {
      Scene scene = clean;
      scene.low_offset = cv::Mat(smallSize(), CV_64F, cv::Scalar(delta));
      const PhaseMaps maps = runScan(scene, deviceHigh(), deviceLow(), o, 0.5);
      const std::string what = (fixed ? "fixed, " : "reference, ") + std::to_string(delta);
      EXPECT_EQ(maps.valid_fraction, 1.0) << what;
      EXPECT_NEAR(std::remainder(maps.order_residual.centre_rad + 9 * delta, kTwoPi), 0, 0.01)
          << what;
      EXPECT_GT(maps.order_residual.samples, kMinResidualSamples) << what;
      std::set<int> shifts;
      for (int y = 0; y < smallSize().height; ++y) {
        for (int x = 0; x < smallSize().width; ++x) {
          const int k = maps.fringe_order.at<std::int16_t>(y, x);
          const int k0 = ref.fringe_order.at<std::int16_t>(y, x);
          shifts.insert(((k - k0) % 9 + 9) % 9);
        }
      }
      EXPECT_EQ(shifts.size(), 1u) << what;
    }
  }
}

// A head whose centre sits near ±π measures it on either side from scan to
// scan. Taken within ±π of a reference (the calibration's), every scan numbers
// its orders as the reference scan did; without one, a scan across ±π numbers
// them one off, which moves the seam where K wraps and breaks a calibration.
TEST(PhaseEngine, AReferenceKeepsTheOrdersAcrossPi) {
  const Scene clean = testing::rampScene(smallSize(), 110, 80);
  for (bool fixed : {true, false}) {
    PhaseOptions o = fixed ? fixedOptions() : referenceOptions();
    const std::string path = fixed ? "fixed" : "reference";
    Scene below = clean, above = clean;
    // Centres −9δ of π − 0.05 and π + 0.05 (the latter measured as −π + 0.05).
    below.low_offset = cv::Mat(smallSize(), CV_64F, cv::Scalar(-(std::numbers::pi - 0.05) / 9));
    above.low_offset = cv::Mat(smallSize(), CV_64F, cv::Scalar(-(std::numbers::pi + 0.05) / 9));
    const PhaseMaps first = runScan(below, deviceHigh(), deviceLow(), o, 0.5);
    ASSERT_NEAR(first.order_residual.centre_rad, std::numbers::pi - 0.05, 0.01) << path;
    const PhaseMaps unreferenced = runScan(above, deviceHigh(), deviceLow(), o, 0.5);
    EXPECT_NEAR(unreferenced.order_residual.centre_rad, -std::numbers::pi + 0.05, 0.01) << path;
    o.order_reference_rad = first.order_residual.centre_rad;
    const PhaseMaps tied = runScan(above, deviceHigh(), deviceLow(), o, 0.5);
    EXPECT_NEAR(tied.order_residual.centre_rad, std::numbers::pi + 0.05, 0.01) << path;
    EXPECT_EQ(tied.valid_fraction, 1.0) << path;
    int same_tied = 0, same_unreferenced = 0;
    for (int y = 0; y < smallSize().height; ++y) {
      for (int x = 0; x < smallSize().width; ++x) {
        const int k = first.fringe_order.at<std::int16_t>(y, x);
        same_tied += tied.fringe_order.at<std::int16_t>(y, x) == k;
        same_unreferenced += unreferenced.fringe_order.at<std::int16_t>(y, x) == k;
      }
    }
    EXPECT_EQ(same_tied, smallSize().area()) << path;
    EXPECT_EQ(same_unreferenced, 0) << path << ": the unreferenced scan should be one order off";
  }
}

TEST(PhaseEngine, SaturationLevelOptionIsHonoured) {
  // 16-bit frames holding 12-bit counts with a lower saturation level.
  const Scene scene = testing::rampScene(smallSize(), 2000, 1500);  // peaks at 3500
  PhaseOptions o = fixedOptions(12);
  o.saturation_level = 3400;
  EXPECT_EQ(runScan(scene, deviceHigh(), deviceLow(), o).valid_fraction, 0.0);
  o.saturation_level = 3600;
  EXPECT_EQ(runScan(scene, deviceHigh(), deviceLow(), o).valid_fraction, 1.0);
}

// ---- dual-set fusion ---------------------------------------------------------------

TEST(PhaseEngine, FusionLowersPhaseNoise) {
  const double a = 30000, b = 20000, sigma = 400;
  const Scene scene = testing::rampScene(cv::Size(160, 120), a, b);
  for (bool fixed : {true, false}) {
    PhaseEngine engine(scene.absolute_high.size(), stepGeometry(5.0, 25), stepGeometry(5.625, 25),
                       fixed ? fixedOptions(16) : referenceOptions(16));
    const PhaseMaps maps = runScan(scene, stepGeometry(5.0, 25), stepGeometry(5.625, 25),
                                   fixed ? fixedOptions(16) : referenceOptions(16), sigma, 21);
    const ErrorStats high = absoluteError(maps.absolute, maps, scene);
    const ErrorStats fused = absoluteError(maps.fused, maps, scene);
    const double rho = testing::kLowPeriod / testing::kHighPeriod;
    const double gamma =
        engine.noiseGain(FringeSet::High) / (engine.noiseGain(FringeSet::Low) * rho * rho);
    const double theory = 1 - 1 / std::sqrt(1 + gamma);
    const double measured = 1 - fused.rms / high.rms;
    std::printf("%s: Φh rms %.3e, fused rms %.3e rad: %.1f %% lower (theory %.1f %%)\n",
                fixed ? "fixed" : "reference", high.rms, fused.rms, 100 * measured, 100 * theory);
    EXPECT_EQ(maps.valid_fraction, 1.0);
    // Theory says 25.3 %; 19200 samples give the ratio to about 1 %. Ask for >= 15 %.
    EXPECT_GE(measured, 0.15);
    EXPECT_NEAR(measured, theory, 0.04);
  }
}

// ---- engine contract ------------------------------------------------------------

TEST(PhaseEngine, WorkingStateIsAtMost16BytesPerPixel) {
  PhaseEngine fixed(smallSize(), deviceHigh(), deviceLow(), fixedOptions());
  EXPECT_LE(fixed.workingStateBytes(), 16u * smallSize().area());
  EXPECT_GT(fixed.workingStateBytes(), 0u);
  PhaseEngine ref(smallSize(), deviceHigh(), deviceLow(), referenceOptions());
  std::printf("working state: fixed %.1f, reference %.1f bytes/pixel\n",
              static_cast<double>(fixed.workingStateBytes()) / smallSize().area(),
              static_cast<double>(ref.workingStateBytes()) / smallSize().area());
}

TEST(PhaseEngine, KernelVariantsResolveOnlyToWhatThisBuildAndCpuHave) {
  // The baseline is always itself; a variant resolves to itself exactly when it
  // is available, else to a narrower one of its own family, never across.
  EXPECT_EQ(resolveKernelIsa(KernelIsa::kBaseline), KernelIsa::kBaseline);
  EXPECT_EQ(resolveKernelIsa(KernelIsa::kNeon),
            neonKernelsAvailable() ? KernelIsa::kNeon : KernelIsa::kBaseline);
  EXPECT_EQ(resolveKernelIsa(KernelIsa::kAvx2),
            avx2KernelsAvailable() ? KernelIsa::kAvx2 : KernelIsa::kBaseline);
  const KernelIsa avx512 = resolveKernelIsa(KernelIsa::kAvx512);
  EXPECT_EQ(avx512 == KernelIsa::kAvx512, avx512KernelsAvailable());
  EXPECT_NE(avx512, KernelIsa::kNeon);
  // x86 and 32-bit ARM variants never exist in the same build.
  EXPECT_FALSE(neonKernelsAvailable() && avx2KernelsAvailable());
  const KernelIsa automatic = resolveKernelIsa(KernelIsa::kAuto);
  if (neonKernelsAvailable()) {
    EXPECT_EQ(automatic, KernelIsa::kNeon);
  }
  if (avx512KernelsAvailable()) {
    EXPECT_EQ(automatic, KernelIsa::kAvx512);
  }
  if (!neonKernelsAvailable() && !avx2KernelsAvailable()) {
    EXPECT_EQ(automatic, KernelIsa::kBaseline);
  }
}

// The fold of a set's last frame writes the phase and code that a plain fold
// followed by the phase kernel gives, for both pixel depths, every fold mode
// and every kernel build this machine runs (n odd, so vector tails are hit).
template <typename Pixel>
void expectFoldPhaseMatchesFoldThenPhase(KernelIsa isa, FoldMode mode, int max_pixel) {
  constexpr std::size_t kPixels = 1031;
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::int32_t> sum(-(1 << 27), 1 << 27);
  std::uniform_int_distribution<int> pixel(0, max_pixel);
  std::vector<std::uint32_t> c(kPixels), s(kPixels), a(kPixels);
  std::vector<Pixel> frame(kPixels);
  for (std::size_t i = 0; i < kPixels; ++i) {
    c[i] = static_cast<std::uint32_t>(sum(rng));
    s[i] = static_cast<std::uint32_t>(sum(rng));
    a[i] = static_cast<std::uint32_t>(sum(rng)) & ~1u;
    frame[i] = static_cast<Pixel>(pixel(rng));
  }
  c[0] = s[0] = 0;  // the angle of (0, 0) and a zero modulation
  FoldWeights w;
  w.c = -1733;
  w.s = 911;
  w.a = 64;
  w.saturation = static_cast<std::uint32_t>(max_pixel);
  w.max_pixel = static_cast<std::uint32_t>(max_pixel);
  const float code_per_sum = 3.1e-3f;

  std::vector<std::uint32_t> c1 = c, s1 = s, a1 = a;
  foldKernel(isa, mode, frame.data(), kPixels, w, c1.data(), s1.data(), a1.data());
  std::vector<BinaryAngle> phase(kPixels);
  std::vector<std::uint16_t> code(kPixels);
  phaseKernel(isa, c1.data(), s1.data(), kPixels, code_per_sum, phase.data(), code.data());

  std::vector<std::uint32_t> c2 = c, a2 = a;
  foldPhaseKernel(isa, mode, frame.data(), kPixels, w, code_per_sum, c2.data(), s.data(),
                  a2.data());
  int differing = 0;
  for (std::size_t i = 0; i < kPixels; ++i) {
    differing += packedAngle(c2[i]) != phase[i] || packedCode(c2[i]) != code[i] || a2[i] != a1[i];
  }
  EXPECT_EQ(differing, 0) << "isa " << static_cast<int>(isa) << ", mode " << static_cast<int>(mode)
                          << ", " << sizeof(Pixel) * 8 << "-bit";
}

TEST(PhaseEngine, TheFoldThatCompletesASetWritesThePhaseKernelsBits) {
  for (const KernelIsa isa :
       {KernelIsa::kBaseline, KernelIsa::kNeon, KernelIsa::kAvx2, KernelIsa::kAvx512}) {
    if (resolveKernelIsa(isa) != isa) continue;  // not in this build or on this CPU
    for (const FoldMode mode : {FoldMode::kAccumulate, FoldMode::kStartSet, FoldMode::kStartScan}) {
      expectFoldPhaseMatchesFoldThenPhase<std::uint8_t>(isa, mode, 255);
      expectFoldPhaseMatchesFoldThenPhase<std::uint16_t>(isa, mode, 4095);
    }
  }
}

TEST(PhaseEngine, KernelBuildsAndSetOrderGiveIdenticalBits) {
  const cv::Size size(320, 240);
  const Scene scene = testing::rampScene(size, 120, 60);
  PhaseOptions baseline = fixedOptions();
  baseline.kernel_isa = KernelIsa::kBaseline;
  const PhaseMaps a = runScan(scene, deviceHigh(), deviceLow(), baseline, 2.0, 4);
  const PhaseMaps low_first = runScan(scene, deviceHigh(), deviceLow(), baseline, 2.0, 4, true);
  // Same noise draws in a different order of sets differ, so compare noise-free for order.
  const PhaseMaps c = runScan(scene, deviceHigh(), deviceLow(), baseline, 0, 4, false);
  const PhaseMaps d = runScan(scene, deviceHigh(), deviceLow(), baseline, 0, 4, true);
  expectIdenticalMaps(c, d);
  EXPECT_GT(low_first.valid_fraction, 0.99);
  int compared = 0;
  for (KernelIsa isa : {KernelIsa::kAvx2, KernelIsa::kAvx512, KernelIsa::kNeon}) {
    if (resolveKernelIsa(isa) != isa) continue;  // not on this CPU
    PhaseOptions wide = fixedOptions();
    wide.kernel_isa = isa;
    expectIdenticalMaps(a, runScan(scene, deviceHigh(), deviceLow(), wide, 2.0, 4));
    ++compared;
  }
  if (compared == 0) GTEST_SKIP() << "only the baseline kernels run on this CPU";
}

TEST(PhaseEngine, FinalizeIsRepeatableAndResetStartsOver) {
  const Scene scene = testing::rampScene(smallSize(), 120, 60);
  PhaseEngine engine(smallSize(), deviceHigh(), deviceLow(), fixedOptions());
  testing::FringeRenderer renderer(scene, 8, 0, 1);
  const auto fold_all = [&] {
    for (int k = 0; k < 25; ++k)
      engine.fold(FringeSet::Low, k, renderer.render(FringeSet::Low, deviceLow(), k));
    for (int k = 24; k >= 0; --k)
      engine.fold(FringeSet::High, k, renderer.render(FringeSet::High, deviceHigh(), k));
  };
  fold_all();
  const PhaseMaps first = engine.finalize();
  PhaseMaps again;
  engine.finalize(again);
  expectIdenticalMaps(first, again);
  engine.reset();
  EXPECT_THROW(engine.finalize(), std::logic_error);
  fold_all();
  expectIdenticalMaps(first, engine.finalize());
}

// ---- compact finalize ----------------------------------------------------------------

// The compact outputs against the full maps of the same engine: exact where the
// values are the same numbers, within half a code for the rounded texture.
void expectCompactMatchesFull(const CompactPhase& c, const PhaseMaps& m, int bits,
                              const std::string& what) {
  const auto rad = static_cast<float>(2 * std::numbers::pi / 65536.0);
  ASSERT_EQ(c.absolute.type(), CV_32SC1) << what;
  ASSERT_EQ(c.fused.type(), CV_32FC1) << what;
  ASSERT_EQ(c.invalid.type(), CV_8UC1) << what;
  ASSERT_EQ(c.texture.type(), CV_16UC1) << what;
  EXPECT_TRUE(bitIdentical(c.invalid, m.invalid)) << what;
  EXPECT_EQ(c.valid_fraction, m.valid_fraction) << what;
  EXPECT_EQ(c.texture_codes_per_count, 65536.0 / (1 << bits)) << what;
  int valid = 0;
  for (int y = 0; y < m.absolute.rows; ++y) {
    for (int x = 0; x < m.absolute.cols; ++x) {
      const std::int32_t absolute = c.absolute.at<std::int32_t>(y, x);
      const float fused = c.fused.at<float>(y, x);
      const double texture = m.texture.at<float>(y, x) * c.texture_codes_per_count;
      ASSERT_LE(std::abs(c.texture.at<std::uint16_t>(y, x) - std::clamp(texture, 0.0, 65535.0)),
                0.5 + 1e-3)
          << what << " " << x << "," << y;
      if (m.invalid.at<std::uint8_t>(y, x) != 0) {
        ASSERT_EQ(absolute, CompactPhase::kInvalidAbsolute) << what << " " << x << "," << y;
        ASSERT_TRUE(std::isnan(fused)) << what << " " << x << "," << y;
        continue;
      }
      ++valid;
      // Bit for bit: the same float products as the full finalize.
      ASSERT_EQ(std::bit_cast<std::uint32_t>(static_cast<float>(absolute) * rad),
                std::bit_cast<std::uint32_t>(m.absolute.at<float>(y, x)))
          << what << " " << x << "," << y;
      ASSERT_EQ(std::bit_cast<std::uint32_t>(fused * rad),
                std::bit_cast<std::uint32_t>(m.fused.at<float>(y, x)))
          << what << " " << x << "," << y;
      ASSERT_EQ(absolute >> 16, m.fringe_order.at<std::int16_t>(y, x))
          << what << " " << x << "," << y;
      ASSERT_EQ(std::bit_cast<std::uint32_t>(static_cast<float>(absolute & 0xFFFF) * rad),
                std::bit_cast<std::uint32_t>(m.wrapped_high.at<float>(y, x)))
          << what << " " << x << "," << y;
    }
  }
  EXPECT_GT(valid, 0) << what;
}

TEST(PhaseEngine, CompactFinalizeMatchesFullFinalize) {
  // Dark, order-corrupted, saturated and fine columns (as in the flags test), with noise,
  // at 8 and 16 bits, either set first, every kernel build this CPU runs.
  for (int bits : {8, 16}) {
    const double full = (1 << bits) - 1;
    const double count = full / 255.0;
    Scene scene = testing::rampScene(smallSize(), 110 * count, 80 * count);
    scene.modulation.colRange(0, 32).setTo(2.0 * count);
    scene.low_offset = cv::Mat::zeros(smallSize(), CV_64F);
    scene.low_offset.colRange(32, 64).setTo(0.3);
    scene.background.colRange(64, 96).setTo(200.0 * count);
    scene.modulation.colRange(64, 96).setTo(100.0 * count);
    for (bool low_first : {false, true}) {
      for (KernelIsa isa :
           {KernelIsa::kBaseline, KernelIsa::kAvx2, KernelIsa::kAvx512, KernelIsa::kNeon}) {
        if (resolveKernelIsa(isa) != isa) continue;  // not on this CPU
        PhaseOptions o = fixedOptions(bits);
        o.kernel_isa = isa;
        PhaseEngine engine(smallSize(), deviceHigh(), deviceLow(), o);
        testing::FringeRenderer renderer(scene, bits, 0.7 * count, 11);
        const auto fold_set = [&](FringeSet set, const FringeSetGeometry& g) {
          for (int k = 0; k < 25; ++k)
            engine.fold(set, k, renderer.render(set, g, k));
        };
        if (low_first) fold_set(FringeSet::Low, deviceLow());
        fold_set(FringeSet::High, deviceHigh());
        if (!low_first) fold_set(FringeSet::Low, deviceLow());
        CompactPhase compact;
        engine.finalizeCompact(compact);
        const PhaseMaps maps = engine.finalize();
        const std::string what = std::to_string(bits) + " bits" + (low_first ? ", low first" : "") +
                                 ", isa " + std::to_string(static_cast<int>(isa));
        expectCompactMatchesFull(compact, maps, bits, what);
        EXPECT_GT(maps.valid_fraction, 0.2) << what;
        EXPECT_LT(maps.valid_fraction, 0.3) << what;
        // Reusing the memory gives the same bits.
        const uchar* data = compact.absolute.data;
        CompactPhase again = compact;
        engine.finalizeCompact(compact);
        EXPECT_EQ(compact.absolute.data, data);
        EXPECT_TRUE(bitIdentical(compact.absolute, again.absolute)) << what;
      }
    }
  }
}

// Isolated pixels whose low phase is off by 0.335 or 0.36 rad have a residual
// of −3.02 rad (their rounded order still right) or +3.04 rad (rounded one
// order low): both beyond the bound, which stays π/2 because those residuals
// lie near ±π, where the gap rule does not move it. Each sits among 8 trusted
// pixels of a smooth ramp, so its neighbours decide its order, and Φ (of the
// uncorrupted high set) is right. In a 4×4 block of them only the corners
// have 5 trusted neighbours; the other 12 pixels stay invalid.
TEST(PhaseEngine, NeighboursDecideTheOrdersOfIsolatedAmbiguousPixels) {
  Scene scene = testing::rampScene(smallSize(), 110, 80);
  scene.low_offset = cv::Mat::zeros(smallSize(), CV_64F);
  std::vector<cv::Point> isolated;
  for (int y = 4; y < 92; y += 8) {
    for (int x = 4; x < 96; x += 8) {
      scene.low_offset.at<double>(y, x) = (x / 8 + y / 8) % 2 == 0 ? 0.335 : 0.36;
      isolated.emplace_back(x, y);
    }
  }
  const cv::Rect block(108, 40, 4, 4);
  scene.low_offset(block).setTo(0.335);
  const std::size_t decided = isolated.size() + 4;
  for (bool fixed : {true, false}) {
    const std::string what = fixed ? "fixed" : "reference";
    const PhaseMaps maps =
        runScan(scene, deviceHigh(), deviceLow(), fixed ? fixedOptions() : referenceOptions(), 0.5);
    EXPECT_NEAR(maps.order_residual.bound_rad, std::numbers::pi / 2, 1e-6) << what;
    EXPECT_EQ(maps.order_residual.decided_by_neighbours, decided) << what;
    for (const cv::Point& p : isolated) {
      ASSERT_EQ(maps.invalid.at<std::uint8_t>(p), kValid) << what << " " << p;
      const double truth = scene.absolute_high.at<double>(p);
      ASSERT_NEAR(maps.absolute.at<float>(p), truth, 0.05) << what << " " << p;
      ASSERT_EQ(maps.fringe_order.at<std::int16_t>(p), expectedOrder(truth)) << what << " " << p;
      ASSERT_TRUE(std::isfinite(maps.fused.at<float>(p))) << what << " " << p;
    }
    int block_invalid = 0;
    for (int y = block.y; y < block.br().y; ++y)
      for (int x = block.x; x < block.br().x; ++x)
        block_invalid += maps.invalid.at<std::uint8_t>(y, x) == kOrderInconsistent;
    EXPECT_EQ(block_invalid, 12) << what;
    EXPECT_NEAR(maps.valid_fraction, 1.0 - 12.0 / smallSize().area(), 1e-12) << what;
  }
  // The device's compact finalize decides the same pixels, to the bit, with
  // every kernel build this CPU runs.
  for (KernelIsa isa :
       {KernelIsa::kBaseline, KernelIsa::kAvx2, KernelIsa::kAvx512, KernelIsa::kNeon}) {
    if (resolveKernelIsa(isa) != isa) continue;  // not on this CPU
    PhaseOptions o = fixedOptions();
    o.kernel_isa = isa;
    PhaseEngine engine(smallSize(), deviceHigh(), deviceLow(), o);
    testing::FringeRenderer renderer(scene, 8, 0.5, 5);
    for (FringeSet set : {FringeSet::High, FringeSet::Low}) {
      const FringeSetGeometry& g = set == FringeSet::High ? deviceHigh() : deviceLow();
      for (int k = 0; k < 25; ++k)
        engine.fold(set, k, renderer.render(set, g, k));
    }
    CompactPhase compact;
    engine.finalizeCompact(compact);
    const PhaseMaps maps = engine.finalize();
    const std::string what = "isa " + std::to_string(static_cast<int>(isa));
    expectCompactMatchesFull(compact, maps, 8, what);
    EXPECT_EQ(compact.order_residual.decided_by_neighbours, decided) << what;
    EXPECT_EQ(maps.order_residual.decided_by_neighbours, decided) << what;
  }
}

TEST(PhaseEngine, CompactFinalizeNeedsTheFixedPathAndAllFrames) {
  CompactPhase out;
  PhaseEngine fixed(smallSize(), deviceHigh(), deviceLow(), fixedOptions());
  EXPECT_THROW(fixed.finalizeCompact(out), std::logic_error);
  PhaseEngine reference(smallSize(), deviceHigh(), deviceLow(), referenceOptions());
  EXPECT_THROW(reference.finalizeCompact(out), std::logic_error);
}

template <typename Exception>
void expectThrowWith(const std::function<void()>& f, const std::string& fragment) {
  try {
    f();
    FAIL() << "no exception; expected one mentioning '" << fragment << "'";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(PhaseEngine, RejectsBadFramesNamingTheFault) {
  PhaseEngine engine(smallSize(), deviceHigh(), deviceLow(), fixedOptions());
  const cv::Mat good(smallSize(), CV_8UC1, cv::Scalar(100));
  using IA = std::invalid_argument;
  expectThrowWith<IA>([&] { engine.fold(FringeSet::High, 0, cv::Mat(smallSize(), CV_32FC1)); },
                      "32F");
  expectThrowWith<IA>([&] { engine.fold(FringeSet::High, 0, cv::Mat(smallSize(), CV_8UC3)); },
                      "8UC3");
  expectThrowWith<IA>([&] { engine.fold(FringeSet::High, 0, cv::Mat(50, 40, CV_8UC1)); }, "40x50");
  expectThrowWith<IA>([&] { engine.fold(FringeSet::High, 0, cv::Mat()); }, "empty");
  expectThrowWith<IA>([&] { engine.fold(FringeSet::High, 0, cv::Mat(smallSize(), CV_16UC1)); },
                      "16-bit");
  expectThrowWith<std::out_of_range>([&] { engine.fold(FringeSet::Low, 25, good); }, "k = 0..24");
  expectThrowWith<std::out_of_range>([&] { engine.fold(FringeSet::Low, -1, good); }, "low");
  engine.fold(FringeSet::High, 3, good);
  expectThrowWith<std::logic_error>([&] { engine.fold(FringeSet::High, 3, good); },
                                    "already folded");
  expectThrowWith<std::logic_error>([&] { engine.fold(FringeSet::Low, 0, good); },
                                    "1 of 25 frames");
  expectThrowWith<std::logic_error>([&] { (void)engine.finalize(); }, "high 1 of 25");
  // A non-continuous (ROI) frame is fine.
  cv::Mat big(smallSize().height + 2, smallSize().width + 2, CV_8UC1, cv::Scalar(100));
  EXPECT_NO_THROW(
      engine.fold(FringeSet::High, 4, big(cv::Rect(1, 1, smallSize().width, smallSize().height))));

  PhaseEngine deep(smallSize(), deviceHigh(), deviceLow(), fixedOptions(12));
  expectThrowWith<IA>([&] { deep.fold(FringeSet::High, 0, good); }, "8-bit");
}

TEST(PhaseEngine, RejectsBadOptionsPeriodsAndShifts) {
  using IA = std::invalid_argument;
  const auto make = [](FringeSetGeometry h, FringeSetGeometry l, PhaseOptions o) {
    PhaseEngine e(smallSize(), std::move(h), std::move(l), o);
  };
  PhaseOptions o;
  o.bit_depth = 7;
  expectThrowWith<IA>([&] { make(deviceHigh(), deviceLow(), o); }, "bit_depth");
  o = {};
  o.saturation_level = 300;
  expectThrowWith<IA>([&] { make(deviceHigh(), deviceLow(), o); }, "saturation_level");
  o = {};
  o.max_order_error_rad = 4;
  expectThrowWith<IA>([&] { make(deviceHigh(), deviceLow(), o); }, "max_order_error_rad");
  expectThrowWith<IA>([&] { PhaseEngine e(cv::Size(0, 5), deviceHigh(), deviceLow()); }, "empty");
  // Swapped periods: high must be the shorter one.
  expectThrowWith<IA>([&] { make(stepGeometry(5.625, 25), stepGeometry(5.0, 25), {}); },
                      "high period < low");
  expectThrowWith<ShiftSolveError>([&] { make({5.0, {1, 1, 1}}, deviceLow(), {}); }, "high");
  expectThrowWith<ShiftSolveError>(
      [&] {
        make(deviceHigh(), {5.625, {0, 2.8125, 5.625}}, {});
      },
      "low");
  // Defaults are resolved and reported.
  PhaseEngine e(smallSize(), deviceHigh(), deviceLow(), fixedOptions(12));
  EXPECT_EQ(e.options().saturation_level, 4095);
  EXPECT_NEAR(e.options().min_modulation, 0.02 * 4095, 1e-9);
  EXPECT_EQ(e.options().max_order_error_rad, -1);  // -1: from the scan's residual spread
}

}  // namespace
}  // namespace cylscan::algo
