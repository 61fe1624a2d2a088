// SPDX-License-Identifier: Apache-2.0
// Test helper: synthetic fringe frames with a known phase, I_k = A + B cos(φ − δk),
// optional Gaussian noise (fixed seed), rounded and clamped to the bit depth.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "algo/phase_engine.hpp"

namespace cylscan::algo::testing {

inline constexpr double kTwoPi = 2 * std::numbers::pi;
inline constexpr double kHighPeriod = 5.0;
inline constexpr double kLowPeriod = 5.625;

// stage_k = start + k·period/N, optionally quantised to whole motor steps.
inline FringeSetGeometry stepGeometry(double period, int frames, double start = 0,
                                      double span_fraction = 1.0, double motor_step = 0) {
  FringeSetGeometry g{period, {}};
  for (int k = 0; k < frames; ++k) {
    double offset = span_fraction * period * k / frames;
    if (motor_step > 0) offset = std::round(offset / motor_step) * motor_step;
    g.stage_deg.push_back(start + offset);
  }
  return g;
}

// The scan of the device: 25 frames per set, 0.004° motor steps (0.225° rounds).
inline FringeSetGeometry deviceHigh(int frames = 25) {
  return stepGeometry(kHighPeriod, frames, -90.0, 1.0, 0.004);
}
inline FringeSetGeometry deviceLow(int frames = 25) {
  return stepGeometry(kLowPeriod, frames, 87.0, 1.0, 0.004);
}

// What a pixel sees: Φ of the high set (radians; the low set sees Φ·θh/θl), A and B.
struct Scene {
  cv::Mat absolute_high;  // CV_64F, truth Φh in [0, 2π·9)
  cv::Mat background;     // CV_64F, A in counts
  cv::Mat modulation;     // CV_64F, B in counts
  cv::Mat low_offset;     // optional CV_64F, extra phase of the low set only (corrupts orders)
};

inline Scene uniformScene(cv::Size size, double a, double b) {
  Scene s;
  s.absolute_high.create(size, CV_64F);
  s.background = cv::Mat(size, CV_64F, cv::Scalar(a));
  s.modulation = cv::Mat(size, CV_64F, cv::Scalar(b));
  return s;
}

// Φh a smooth ramp across the image over `orders` high periods, plus `phase0`.
inline Scene rampScene(cv::Size size, double a, double b, double orders = 8.8,
                       double phase0 = 0.05) {
  Scene s = uniformScene(size, a, b);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      const double t = (x + size.width * static_cast<double>(y)) / size.area();
      s.absolute_high.at<double>(y, x) = phase0 + t * orders * kTwoPi;
    }
  }
  return s;
}

// Frame k of a set (period of the set, geometry), with noise sigma (counts).
class FringeRenderer {
 public:
  FringeRenderer(const Scene& scene, int bit_depth, double noise_sigma, std::uint64_t seed)
      : scene_(scene), bit_depth_(bit_depth), sigma_(noise_sigma), rng_(seed) {}

  cv::Mat render(FringeSet set, const FringeSetGeometry& g, int k) {
    const double scale = set == FringeSet::High ? 1.0 : kHighPeriod / g.period_deg;
    const double delta =
        kTwoPi * (g.stage_deg[static_cast<std::size_t>(k)] - g.stage_deg[0]) / g.period_deg;
    const double max_value = (1 << bit_depth_) - 1;
    const cv::Size size = scene_.absolute_high.size();
    cv::Mat frame(size, bit_depth_ == 8 ? CV_8UC1 : CV_16UC1);
    std::normal_distribution<double> noise(0.0, 1.0);
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        double phi = scene_.absolute_high.at<double>(y, x) * scale;
        if (set == FringeSet::Low && !scene_.low_offset.empty()) {
          phi += scene_.low_offset.at<double>(y, x);
        }
        double v = scene_.background.at<double>(y, x) +
                   scene_.modulation.at<double>(y, x) * std::cos(phi - delta);
        if (sigma_ > 0) v += sigma_ * noise(rng_);
        v = std::clamp(std::round(v), 0.0, max_value);
        if (bit_depth_ == 8) {
          frame.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(v);
        } else {
          frame.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(v);
        }
      }
    }
    return frame;
  }

 private:
  const Scene& scene_;
  int bit_depth_;
  double sigma_;
  std::mt19937_64 rng_;
};

// Folds every frame of both sets (the high set first unless low_first).
inline PhaseMaps runScan(const Scene& scene, const FringeSetGeometry& high,
                         const FringeSetGeometry& low, PhaseOptions options, double noise_sigma = 0,
                         std::uint64_t seed = 7, bool low_first = false) {
  PhaseEngine engine(scene.absolute_high.size(), high, low, options);
  FringeRenderer renderer(scene, options.bit_depth, noise_sigma, seed);
  const auto fold_set = [&](FringeSet set, const FringeSetGeometry& g) {
    for (int k = 0; k < static_cast<int>(g.stage_deg.size()); ++k) {
      engine.fold(set, k, renderer.render(set, g, k));
    }
  };
  if (low_first) {
    fold_set(FringeSet::Low, low);
    fold_set(FringeSet::High, high);
  } else {
    fold_set(FringeSet::High, high);
    fold_set(FringeSet::Low, low);
  }
  return engine.finalize();
}

// The difference of two angles wrapped to [-π, π).
inline double angleDifference(double a, double b) {
  double d = std::fmod(a - b, kTwoPi);
  if (d < -std::numbers::pi) d += kTwoPi;
  if (d >= std::numbers::pi) d -= kTwoPi;
  return d;
}

}  // namespace cylscan::algo::testing
