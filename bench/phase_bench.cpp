// SPDX-License-Identifier: Apache-2.0
// Benchmarks of the phase engine at 1000x800 with 8-bit frames, one core:
// the fixed-point path, the double reference path, and an OpenCV float baseline
// written the way a user would write it. Run e.g.
//   cylscan_bench --benchmark_repetitions=5 --benchmark_min_time=0.2
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "algo/phase_engine.hpp"
#include "bench/fringe_sets.hpp"

namespace {

using cylscan::FringeSet;
using cylscan::algo::CompactPhase;
using cylscan::algo::FringeSetGeometry;
using cylscan::algo::PhaseEngine;
using cylscan::algo::PhaseMaps;
using cylscan::algo::PhaseOptions;

constexpr double kTwoPi = 2 * std::numbers::pi;
constexpr int kWidth = 1000;
constexpr int kHeight = 800;
constexpr int kFrames = cylscan::bench::kFramesPerSet;

// Two sets of 8-bit frames of a ramp over all 9 fringe orders, with sensor noise.
struct Scan {
  FringeSetGeometry high = cylscan::bench::highSet();
  FringeSetGeometry low = cylscan::bench::lowSet();
  std::vector<cv::Mat> frames[2];

  Scan() {
    std::mt19937 rng(1);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    for (int s = 0; s < 2; ++s) {
      const FringeSetGeometry& g = s == 0 ? high : low;
      const double scale = s == 0 ? 1.0 : 5.0 / 5.625;
      for (int k = 0; k < kFrames; ++k) {
        const double delta = kTwoPi * (g.stage_deg[k] - g.stage_deg[0]) / g.period_deg;
        cv::Mat f(cv::Size(kWidth, kHeight), CV_8UC1);
        for (int y = 0; y < kHeight; ++y) {
          for (int x = 0; x < kWidth; ++x) {
            const double phi = (0.05 + 8.8 * x / kWidth) * kTwoPi * scale;
            const double v = 110 + 80 * std::cos(phi - delta) + noise(rng);
            f.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(v);
          }
        }
        frames[s].push_back(f);
      }
    }
  }
};

const Scan& scan() {
  static const Scan s;
  return s;
}

PhaseOptions options(bool fixed) {
  PhaseOptions o;
  o.fixed_point = fixed;
  return o;
}

void foldAll(PhaseEngine& engine, const Scan& s) {
  for (int k = 0; k < kFrames; ++k)
    engine.fold(FringeSet::High, k, s.frames[0][k]);
  for (int k = 0; k < kFrames; ++k)
    engine.fold(FringeSet::Low, k, s.frames[1][k]);
}

void setCounters(benchmark::State& state, const PhaseEngine& engine) {
  state.counters["state_B_per_px"] =
      static_cast<double>(engine.workingStateBytes()) / (kWidth * kHeight);
}

// ---- the engine ------------------------------------------------------------------

// One 8-bit frame folded (the high set; every 25 frames the engine is reset, untimed).
void BM_Fold(benchmark::State& state, bool fixed) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(fixed));
  int k = 0;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    engine.fold(FringeSet::High, k, s.frames[0][k]);
    if (++k == kFrames) {
      state.PauseTiming();
      engine.reset();
      k = 0;
      state.ResumeTiming();
    }
  }
  setCounters(state, engine);
}

// The fold of a set's last frame, which also computes the set's phase and
// modulation (the fixed path; the reference path folds it as any other frame).
// The set's other frames are folded untimed.
void BM_FoldCompletingSet(benchmark::State& state, bool fixed) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(fixed));
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    state.PauseTiming();
    engine.reset();
    for (int k = 0; k + 1 < kFrames; ++k)
      engine.fold(FringeSet::High, k, s.frames[0][k]);
    state.ResumeTiming();
    engine.fold(FringeSet::High, kFrames - 1, s.frames[0][kFrames - 1]);
  }
  setCounters(state, engine);
}

// Both sets' unwrapping, fusion and all output maps (maps reused); the
// fixed path's atan2 of each set is in the fold that completes it.
void BM_Finalize(benchmark::State& state, bool fixed) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(fixed));
  foldAll(engine, s);
  PhaseMaps maps;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    engine.finalize(maps);
    benchmark::DoNotOptimize(maps.valid_fraction);
  }
  setCounters(state, engine);
}

// The device's finalize: CompactPhase (absolute, fused, invalid, texture: 11 B/px written).
void BM_FinalizeCompact(benchmark::State& state) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(true));
  foldAll(engine, s);
  CompactPhase out;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    engine.finalizeCompact(out);
    benchmark::DoNotOptimize(out.valid_fraction);
  }
  setCounters(state, engine);
}

// The same, allocating fresh maps every time (PhaseMaps finalize()).
void BM_FinalizeNewMaps(benchmark::State& state, bool fixed) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(fixed));
  foldAll(engine, s);
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    PhaseMaps maps = engine.finalize();
    benchmark::DoNotOptimize(maps.valid_fraction);
  }
}

// The whole 2x25-frame scan: reset, 50 folds, finalize (maps reused).
void BM_Pipeline(benchmark::State& state, bool fixed) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(fixed));
  PhaseMaps maps;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    engine.reset();
    foldAll(engine, s);
    engine.finalize(maps);
    benchmark::DoNotOptimize(maps.valid_fraction);
  }
  setCounters(state, engine);
}

// The whole 2x25-frame scan with the device's compact finalize.
void BM_PipelineCompact(benchmark::State& state) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  PhaseEngine engine(cv::Size(kWidth, kHeight), s.high, s.low, options(true));
  CompactPhase out;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    engine.reset();
    foldAll(engine, s);
    engine.finalizeCompact(out);
    benchmark::DoNotOptimize(out.valid_fraction);
  }
  setCounters(state, engine);
}

BENCHMARK_CAPTURE(BM_Fold, fixed, true);
BENCHMARK_CAPTURE(BM_Fold, double, false);
BENCHMARK_CAPTURE(BM_FoldCompletingSet, fixed, true)->Iterations(100);
BENCHMARK_CAPTURE(BM_Finalize, fixed, true);
BENCHMARK_CAPTURE(BM_Finalize, double, false);
BENCHMARK_CAPTURE(BM_FinalizeNewMaps, fixed, true);
BENCHMARK(BM_FinalizeCompact);
BENCHMARK_CAPTURE(BM_Pipeline, fixed, true);
BENCHMARK_CAPTURE(BM_Pipeline, double, false);
BENCHMARK(BM_PipelineCompact);

// ---- OpenCV float baseline, as a user would write it ------------------------------

struct OpenCvBaseline {
  std::vector<double> cos_high, sin_high, cos_low, sin_low;
  cv::Mat frame_f, acc_c[2], acc_s[2], acc_a[2];
  cv::Mat phase_high, phase_low, equivalent, negative, order_real, order, order_f, absolute;

  explicit OpenCvBaseline(const Scan& s) {
    for (int k = 0; k < kFrames; ++k) {
      const double dh = kTwoPi * (s.high.stage_deg[k] - s.high.stage_deg[0]) / 5.0;
      const double dl = kTwoPi * (s.low.stage_deg[k] - s.low.stage_deg[0]) / 5.625;
      cos_high.push_back(std::cos(dh));
      sin_high.push_back(std::sin(dh));
      cos_low.push_back(std::cos(dl));
      sin_low.push_back(std::sin(dl));
    }
    reset();
  }

  void reset() {
    for (int i = 0; i < 2; ++i) {
      acc_c[i] = cv::Mat::zeros(cv::Size(kWidth, kHeight), CV_32F);
      acc_s[i] = cv::Mat::zeros(cv::Size(kWidth, kHeight), CV_32F);
      acc_a[i] = cv::Mat::zeros(cv::Size(kWidth, kHeight), CV_32F);
    }
  }

  void fold(int set, int k, const cv::Mat& frame) {
    const double c = set == 0 ? cos_high[k] : cos_low[k];
    const double s = set == 0 ? sin_high[k] : sin_low[k];
    frame.convertTo(frame_f, CV_32F);
    cv::scaleAdd(frame_f, c, acc_c[set], acc_c[set]);
    cv::scaleAdd(frame_f, s, acc_s[set], acc_s[set]);
    acc_a[set] += frame_f;
  }

  void finalize() {
    cv::phase(acc_c[0], acc_s[0], phase_high);  // atan2(S, C) in [0, 2π)
    cv::phase(acc_c[1], acc_s[1], phase_low);
    cv::subtract(phase_high, phase_low, equivalent);
    cv::compare(equivalent, 0, negative, cv::CMP_LT);
    cv::add(equivalent, cv::Scalar(kTwoPi), equivalent, negative);
    // K = round((9·φeq − φh) / 2π), Φ = φh + 2πK
    cv::addWeighted(equivalent, 9 / kTwoPi, phase_high, -1 / kTwoPi, 0, order_real);
    order_real.convertTo(order, CV_32S);
    order.convertTo(order_f, CV_32F, kTwoPi);
    cv::add(phase_high, order_f, absolute);
  }
};

void BM_OpenCvFold(benchmark::State& state) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  OpenCvBaseline b(s);
  int k = 0;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    b.fold(0, k, s.frames[0][k]);
    if (++k == kFrames) k = 0;
  }
  state.counters["state_B_per_px"] = 4.0 * 6;
}

void BM_OpenCvFinalize(benchmark::State& state) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  OpenCvBaseline b(s);
  for (int k = 0; k < kFrames; ++k)
    b.fold(0, k, s.frames[0][k]);
  for (int k = 0; k < kFrames; ++k)
    b.fold(1, k, s.frames[1][k]);
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    b.finalize();
    benchmark::DoNotOptimize(b.absolute.data);
  }
}

void BM_OpenCvPipeline(benchmark::State& state) {
  cv::setNumThreads(1);
  const Scan& s = scan();
  OpenCvBaseline b(s);
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores)
    for (int i = 0; i < 2; ++i) {
      b.acc_c[i].setTo(0);
      b.acc_s[i].setTo(0);
      b.acc_a[i].setTo(0);
    }
    for (int k = 0; k < kFrames; ++k)
      b.fold(0, k, s.frames[0][k]);
    for (int k = 0; k < kFrames; ++k)
      b.fold(1, k, s.frames[1][k]);
    b.finalize();
    benchmark::DoNotOptimize(b.absolute.data);
  }
  state.counters["state_B_per_px"] = 4.0 * 6;
}

BENCHMARK(BM_OpenCvFold);
BENCHMARK(BM_OpenCvFinalize);
BENCHMARK(BM_OpenCvPipeline);

}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  scan();  // render the frames before timing anything
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
