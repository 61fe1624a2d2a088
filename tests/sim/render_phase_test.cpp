// SPDX-License-Identifier: Apache-2.0
// Rendered fringes lie where the geometry says: the phase measured from the
// frames with an independent least-squares fit matches the analytic wall
// angle of each pixel's surface point, with the sign convention of
// docs/formats.md, capture bundle:
// I_k = A + B cos(φ − δk), δk = 2π (ρk − ρ0) / θ.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <numbers>

#include "drivers/sim/renderer.hpp"
#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using test::lsqPhase;
using test::wrapPi;
constexpr double kPi = std::numbers::pi;

struct SetResult {
  double rms = 0, max = 0, mean_modulation = 0;
  int pixels = 0;
};

// Renders one set of N frames at executed (step-quantised) angles and
// compares the measured phase with the analytic one.
SetResult measureSet(const HeadConfig& config, const Scene& scene, double start_deg, double period,
                     double half_offset, int n, std::uint64_t seed) {
  const CameraModel cam(config.cameras.front());
  const CylindricalProjector proj(config.projector);
  const PixelGeometry g = tracePixels(scene, cam, proj);
  const NoiseTable noise(seed);
  const double spd = config.stage.stepsPerDeg();
  std::vector<cv::Mat> frames;
  std::vector<double> deltas;
  for (int k = 0; k < n; ++k) {
    const double rho = std::round((start_deg + k * period / n) * spd) / spd;
    Exposure e;
    e.stage_deg[0] = rho;
    e.light[0] = true;
    e.bit_depth = config.cameras.front().bit_depth;
    e.noise_scale = config.noise.scale;
    e.noise_key = static_cast<std::uint64_t>(k);
    frames.push_back(renderFrame(g, proj, e, noise));
    deltas.push_back(2 * kPi * (rho - start_deg) / period);
  }
  cv::Mat modulation;
  const cv::Mat phase = lsqPhase(frames, deltas, &modulation);
  SetResult r;
  double sum2 = 0, sum_mod = 0;
  for (int v = 0; v < phase.rows; ++v) {
    for (int u = 0; u < phase.cols; ++u) {
      if (!(g.flags.at<std::uint8_t>(v, u) & PixelGeometry::kLit)) continue;
      const cv::Vec3d p = g.points.at<cv::Vec3d>(v, u);
      const double beta = proj.wallAngleDeg(Vec3(p[0], p[1], p[2]), start_deg);
      const double truth = 2 * kPi * (beta - half_offset) / period;
      const double err = wrapPi(phase.at<double>(v, u) - truth);
      sum2 += err * err;
      r.max = std::max(r.max, std::abs(err));
      sum_mod += modulation.at<double>(v, u);
      ++r.pixels;
    }
  }
  r.rms = std::sqrt(sum2 / r.pixels);
  r.mean_modulation = sum_mod / r.pixels;
  return r;
}

HeadConfig idealHead(int bits) {
  HeadConfig c = test::smallHead(160, 128, 0.0);
  c.projector.eccentricity_mm = 0;  // shifts exactly 2π(ρk − ρ0)/θ
  for (auto& cam : c.cameras)
    cam.bit_depth = bits;
  return c;
}

TEST(RenderPhase, HighAndLowSetsMatchTheGeometryWithTheSpecSign) {
  const HeadConfig c = idealHead(12);
  const Scene scene = test::planeScene(580);
  const SetResult high = measureSet(c, scene, 236.0, 5.0, 0.0, 25, 1);
  const SetResult low = measureSet(c, scene, 56.0, 5.625, 180.0, 25, 1);
  EXPECT_GT(high.pixels, 160 * 128 * 9 / 10);
  EXPECT_LT(high.rms, 0.002);
  EXPECT_LT(high.max, 0.01);
  EXPECT_LT(low.rms, 0.002);
  EXPECT_LT(low.max, 0.01);
}

TEST(RenderPhase, TiltedPlaneAndSphereToo) {
  const HeadConfig c = idealHead(12);
  Scene scene;
  scene.objects.push_back(
      {"plane", Plane{Vec3(0, 0, 600), Vec3(0.2, -0.1, -1).normalized(), std::nullopt}, 0.7});
  scene.objects.push_back({"sphere", Sphere{Vec3(-20, 10, 560), 40}, 0.9});
  const SetResult high = measureSet(c, scene, 236.0, 5.0, 0.0, 25, 2);
  EXPECT_LT(high.rms, 0.003);
}

TEST(RenderPhase, TheOppositeSignConventionWouldNotMatch) {
  // The same frames analysed with δk of the other sign give the mirrored
  // phase: an error of order 1 rad, so the test above can fail.
  const HeadConfig c = idealHead(12);
  const CameraModel cam(c.cameras.front());
  const CylindricalProjector proj(c.projector);
  const PixelGeometry g = tracePixels(test::planeScene(), cam, proj);
  const NoiseTable noise(1);
  std::vector<cv::Mat> frames;
  std::vector<double> deltas;
  for (int k = 0; k < 25; ++k) {
    Exposure e;
    e.stage_deg[0] = 236.0 + 0.2 * k;
    e.light[0] = true;
    e.bit_depth = 12;
    e.noise_scale = 0;
    frames.push_back(renderFrame(g, proj, e, noise));
    deltas.push_back(-2 * kPi * 0.2 * k / 5.0);
  }
  const cv::Mat phase = lsqPhase(frames, deltas);
  double mirrored2 = 0, wrong2 = 0;
  int n = 0;
  for (int v = 0; v < phase.rows; v += 4) {
    for (int u = 0; u < phase.cols; u += 4) {
      const cv::Vec3d p = g.points.at<cv::Vec3d>(v, u);
      const double truth = 2 * kPi * proj.wallAngleDeg(Vec3(p[0], p[1], p[2]), 236.0) / 5.0;
      mirrored2 += std::pow(wrapPi(phase.at<double>(v, u) + truth), 2);
      wrong2 += std::pow(wrapPi(phase.at<double>(v, u) - truth), 2);
      ++n;
    }
  }
  EXPECT_LT(std::sqrt(mirrored2 / n), 0.01);
  EXPECT_GT(std::sqrt(wrong2 / n), 0.5);
}

TEST(RenderPhase, DefaultNoiseGivesMilliradianPhaseNoise) {
  // The default noise (8-bit, full well 10.5 ke−, scale 0.3) with N = 25 and
  // B ≈ 100 counts: phase noise of 1–2.5 mrad (docs/virtual-head.md).
  HeadConfig c = test::smallHead(160, 128, defaultHeadConfig().noise.scale);
  c.projector.eccentricity_mm = 0;
  const SetResult high = measureSet(c, test::planeScene(580), 236.0, 5.0, 0.0, 25, 7);
  std::cout << "[ phase noise ] high set: " << high.rms * 1e3 << " mrad RMS, modulation "
            << high.mean_modulation << " counts\n";
  EXPECT_GT(high.mean_modulation, 80);
  EXPECT_LT(high.mean_modulation, 120);
  EXPECT_GT(high.rms, 0.001);
  EXPECT_LT(high.rms, 0.0025);
}

TEST(RenderPhase, EccentricityBendsThePhaseOnlySlightly) {
  HeadConfig c = idealHead(12);
  c.projector.eccentricity_mm = defaultHeadConfig().projector.eccentricity_mm;
  const SetResult high = measureSet(c, test::planeScene(580), 236.0, 5.0, 0.0, 25, 1);
  // Unequal true shifts: a small systematic error against the nominal δk.
  EXPECT_GT(high.max, 1e-4);
  EXPECT_LT(high.rms, 0.05);
}

TEST(RenderPhase, RenderTimeOfAFullFrame) {
  // Printed, not asserted.
  const HeadConfig c = defaultHeadConfig();
  const CameraModel cam(c.cameras.front());
  const CylindricalProjector proj(c.projector);
  auto t0 = std::chrono::steady_clock::now();
  const PixelGeometry g = tracePixels(test::planeScene(), cam, proj);
  auto t1 = std::chrono::steady_clock::now();
  const NoiseTable noise(1);
  Exposure e;
  e.light[0] = true;
  e.stage_deg[0] = 236;
  e.noise_scale = c.noise.scale;
  const int n = 10;
  for (int k = 0; k < n; ++k) {
    e.noise_key = static_cast<std::uint64_t>(k);
    const cv::Mat f = renderFrame(g, proj, e, noise);
    ASSERT_EQ(f.cols, 1000);
  }
  auto t2 = std::chrono::steady_clock::now();
  const auto ms = [](auto a, auto b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  std::cout << "[ render time ] 1000x800: trace " << ms(t0, t1) << " ms once, frame "
            << ms(t1, t2) / n << " ms\n";
}

}  // namespace
}  // namespace cylscan::sim
