// SPDX-License-Identifier: Apache-2.0
// A fixed amount of phase-engine work, for counting instructions per pixel on
// a target the build machine cannot time (bench/instructions/count.sh runs it
// under qemu-user and counts every instruction it executes):
//   cylscan_kernel_work WIDTH HEIGHT setup|fold|finalize [auto|baseline]
// setup makes the two 25-frame sets; fold also folds all 50 frames; finalize
// also runs the device's compact finalize. Differences between the three
// counts, divided by the pixels, are each stage's instructions per pixel: the
// program's start, the library loading and the frame synthesis cancel out.
// The last argument picks the kernels' build: the widest this CPU runs (the
// default) or the target's baseline.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <string>
#include <system_error>
#include <vector>

#include <opencv2/core.hpp>

#include "algo/phase_engine.hpp"
#include "bench/fringe_sets.hpp"

namespace {

using cylscan::FringeSet;
using cylscan::algo::CompactPhase;
using cylscan::algo::FringeSetGeometry;
using cylscan::algo::KernelIsa;
using cylscan::algo::PhaseEngine;
using cylscan::algo::PhaseOptions;

constexpr int kFrames = cylscan::bench::kFramesPerSet;
constexpr double kTwoPi = 2 * std::numbers::pi;

// The benchmark's scene (a ramp over all nine fringe orders, A = 110, B = 80)
// with a cheap noise: each row is the same fringe row plus xorshift noise of
// ±2 counts, so that making the frames costs few instructions per pixel.
std::vector<cv::Mat> frames(const FringeSetGeometry& g, double scale, cv::Size size) {
  std::vector<cv::Mat> out;
  std::uint32_t state = 2463534242u;
  for (int k = 0; k < kFrames; ++k) {
    const double delta = kTwoPi * (g.stage_deg[k] - g.stage_deg[0]) / g.period_deg;
    std::vector<int> row(static_cast<std::size_t>(size.width));
    for (int x = 0; x < size.width; ++x) {
      const double phi = (0.05 + 8.8 * x / size.width) * kTwoPi * scale;
      row[static_cast<std::size_t>(x)] =
          static_cast<int>(std::lround(110 + 80 * std::cos(phi - delta)));
    }
    cv::Mat f(size, CV_8UC1);
    for (int y = 0; y < size.height; ++y) {
      auto* p = f.ptr<std::uint8_t>(y);
      for (int x = 0; x < size.width; ++x) {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        p[x] = static_cast<std::uint8_t>(row[static_cast<std::size_t>(x)] +
                                         static_cast<int>(state % 5) - 2);
      }
    }
    out.push_back(f);
  }
  return out;
}

// A side of the image from the command line; 0 when it is not a whole number.
int side(const char* text) {
  int value = 0;
  const char* end = text + std::strlen(text);
  const auto [at, error] = std::from_chars(text, end, value);
  return error == std::errc{} && at == end ? value : 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string stage = argc >= 4 ? argv[3] : "";
  const std::string isa = argc == 5 ? argv[4] : "auto";
  if (argc > 5 || (stage != "setup" && stage != "fold" && stage != "finalize") ||
      (isa != "auto" && isa != "baseline")) {
    std::fprintf(stderr, "usage: %s WIDTH HEIGHT setup|fold|finalize [auto|baseline]\n", argv[0]);
    return 2;
  }
  const cv::Size size(side(argv[1]), side(argv[2]));
  if (size.width < 16 || size.height < 1 || size.area() > 16'000'000) {
    std::fprintf(
        stderr,
        "%s: WIDTH (16 or more) and HEIGHT (1 or more, 16 Mpixel at most) are wrong: '%s' '%s'\n",
        argv[0], argv[1], argv[2]);
    return 2;
  }
  const FringeSetGeometry high = cylscan::bench::highSet();
  const FringeSetGeometry low = cylscan::bench::lowSet();
  const std::vector<cv::Mat> sets[2] = {frames(high, 1.0, size), frames(low, 5.0 / 5.625, size)};
  PhaseOptions options;
  options.kernel_isa = isa == "auto" ? KernelIsa::kAuto : KernelIsa::kBaseline;
  PhaseEngine engine(size, high, low, options);
  CompactPhase out;
  if (stage != "setup") {
    for (int k = 0; k < kFrames; ++k)
      engine.fold(FringeSet::High, k, sets[0][k]);
    for (int k = 0; k < kFrames; ++k)
      engine.fold(FringeSet::Low, k, sets[1][k]);
  }
  if (stage == "finalize") engine.finalizeCompact(out);
  // The valid share shows that the work was the real one: valid pixels are
  // unwrapped and fused, invalid ones stop early.
  std::printf("%s %dx%d valid %.3f\n", stage.c_str(), size.width, size.height, out.valid_fraction);
  return 0;
}
