// SPDX-License-Identifier: Apache-2.0
// Helpers for the virtual-head tests: a small-resolution head, a line driver,
// and an independent least-squares phase (not algo/: the tests check the
// virtual head against geometry, nothing else).
#pragma once

#include <chrono>
#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

#include <opencv2/core.hpp>

#include "drivers/sim/head_config.hpp"
#include "drivers/sim/virtual_head.hpp"

namespace cylscan::sim::test {

using namespace std::chrono_literals;

// The default head at a small resolution, noiseless unless asked.
inline HeadConfig smallHead(int width = 200, int height = 160, double noise = 0.0) {
  HeadConfig c = withResolution(defaultHeadConfig(), width, height);
  c.noise.scale = noise;
  return c;
}

inline Scene planeScene(double z = 580.0, double albedo = 0.8) {
  Scene s;
  s.name = "plane";
  s.objects.push_back({"plane", Plane{Vec3(0, 0, z), Vec3(0, 0, -1), std::nullopt}, albedo});
  return s;
}

// Drives the head's lines like firmware: step pulses at a given rate.
class LineDriver {
 public:
  explicit LineDriver(VirtualHead& head) : head_(head), clock_(head.clock()) {
    step = head.gpio().requestOutput(spec("step"), false);
    dir = head.gpio().requestOutput(spec("dir"), true);
    enable = head.gpio().requestOutput(spec("enable"), true);
    trigger = head.gpio().requestOutput(spec("trigger"), false);
    light = head.gpio().requestOutput(spec("light"), true);
  }
  static drivers::LineSpec spec(const char* name) {
    drivers::LineSpec s;
    s.name = name;
    s.role = name;
    return s;
  }
  // n pulses, one every `interval`, the first one `interval` from now.
  void pulses(int n, std::chrono::nanoseconds interval) {
    for (int i = 0; i < n; ++i) {
      const auto t = clock_.now() + interval;
      clock_.sleepUntil(t);
      step->set(true);
      clock_.sleepUntil(t + 2us);
      step->set(false);
    }
  }
  // Moves by `steps` (signed) at a safe rate (below the start/stop rate).
  void move(int steps) {
    dir->set(steps >= 0);
    pulses(std::abs(steps), 2ms);
    clock_.sleepUntil(clock_.now() + 200ms);
  }
  void pulseTrigger() {
    trigger->set(true);
    clock_.sleepUntil(clock_.now() + 10us);
    trigger->set(false);
  }

  std::unique_ptr<drivers::OutputLine> step, dir, enable, trigger, light;

 private:
  VirtualHead& head_;
  drivers::Clock& clock_;
};

// Least-squares phase of I_k = A + B cos(φ − δk) for each pixel; φ in [0, 2π).
inline cv::Mat lsqPhase(const std::vector<cv::Mat>& frames, const std::vector<double>& deltas,
                        cv::Mat* modulation = nullptr) {
  // Normal equations of [1, cos δ, sin δ] (shifts need not be equal).
  cv::Matx33d m = cv::Matx33d::zeros();
  for (double d : deltas) {
    const cv::Vec3d r(1, std::cos(d), std::sin(d));
    m += r * r.t();
  }
  const cv::Matx33d inv = m.inv();
  cv::Mat phase(frames[0].size(), CV_64F), mod(frames[0].size(), CV_64F);
  for (int v = 0; v < phase.rows; ++v) {
    for (int u = 0; u < phase.cols; ++u) {
      cv::Vec3d b(0, 0, 0);
      for (std::size_t k = 0; k < frames.size(); ++k) {
        cv::Mat f;
        const double i = frames[k].depth() == CV_8U ? frames[k].at<std::uint8_t>(v, u)
                                                    : frames[k].at<std::uint16_t>(v, u);
        b += i * cv::Vec3d(1, std::cos(deltas[k]), std::sin(deltas[k]));
      }
      const cv::Vec3d x = inv * b;  // A, B cos φ, B sin φ
      double p = std::atan2(x[2], x[1]);
      if (p < 0) p += 2 * std::numbers::pi;
      phase.at<double>(v, u) = p;
      mod.at<double>(v, u) = std::hypot(x[1], x[2]);
    }
  }
  if (modulation) *modulation = mod;
  return phase;
}

inline double wrapPi(double a) {
  return std::remainder(a, 2 * std::numbers::pi);
}

}  // namespace cylscan::sim::test
