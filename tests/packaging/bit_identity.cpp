// SPDX-License-Identifier: Apache-2.0
// cylscan_bit_identity: digests of what the device computes from a scan — the
// fixed-point phase path (CompactPhase and PhaseMaps), the reconstruction
// (quasi-calibration evaluation to XYZ and depth) and the calibration file's
// bytes — for a synthetic scan, so that two builds (amd64 and a cross build
// run under qemu-user) can be shown to give the same bits.
//
//   cylscan_bit_identity                 print "name digest" lines
//   cylscan_bit_identity --expect FILE   compare with FILE (another build's
//                                        output); exit 1 naming what differs
//
// The input frames are made with integer arithmetic only (a fixed-point
// sine, a xorshift generator for the noise), so both builds start from the
// same frames whatever their libm; their digest is printed too, so a
// difference in the input is told apart from one in the computation. NaN
// (invalid) values are hashed as one pattern: an ARM and an x86 CPU give
// different NaN bits for the same invalid operation, and which pixels are
// invalid is compared bit for bit through the invalid masks.
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "algo/phase_engine.hpp"
#include "algo/quasi_calibration.hpp"

namespace {

using namespace cylscan::algo;
using cylscan::FringeSet;
using cylscan::PhaseSource;

constexpr int kWidth = 320;
constexpr int kHeight = 240;
constexpr int kFrames = 25;
constexpr int kBitDepth = 12;

// FNV-1a, 64 bit, over a matrix's elements in row order; NaN floats as one pattern.
class Digest {
 public:
  void add(const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
      h_ ^= p[i];
      h_ *= 0x100000001b3ULL;
    }
  }
  void add(const cv::Mat& m) {
    const bool floats = m.depth() == CV_32F;
    const std::size_t row_bytes = m.cols * m.elemSize();
    for (int y = 0; y < m.rows; ++y) {
      const unsigned char* row = m.ptr<unsigned char>(y);
      if (!floats) {
        add(row, row_bytes);
        continue;
      }
      for (std::size_t i = 0; i < row_bytes; i += sizeof(float)) {
        float v;
        std::memcpy(&v, row + i, sizeof v);
        const std::uint32_t bits =
            v != v ? 0x7fc00000U : std::bit_cast<std::uint32_t>(v);  // NaN: one pattern
        add(&bits, sizeof bits);
      }
    }
  }
  std::string hex() const {
    char s[17];
    std::snprintf(s, sizeof s, "%016llx", static_cast<unsigned long long>(h_));
    return s;
  }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ULL;
};

std::string digestOf(const cv::Mat& m) {
  Digest d;
  d.add(m);
  return d.hex();
}

// sin of a binary angle (65536 per turn) in Q15, by a parabola refined once:
// integer operations only, so every build gives the same value.
std::int32_t sinQ15(std::uint32_t angle) {
  // x in [-32768, 32768) for [-π, π).
  const std::int32_t x = static_cast<std::int16_t>(static_cast<std::uint16_t>(angle));
  const std::int64_t ax = x < 0 ? -x : x;
  std::int64_t y = 4 * static_cast<std::int64_t>(x) - (4 * x * ax) / 32768;  // Q15, |y| <= 32768
  const std::int64_t ay = y < 0 ? -y : y;
  y += ((y * ay) / 32768 - y) * 225 / 1000;
  return static_cast<std::int32_t>(y);
}

class Xorshift {
 public:
  explicit Xorshift(std::uint64_t seed) : s_(seed) {}
  std::uint64_t next() {
    s_ ^= s_ << 13;
    s_ ^= s_ >> 7;
    s_ ^= s_ << 17;
    return s_;
  }
  // Integer noise in [-spread, spread].
  int noise(int spread) { return static_cast<int>(next() % (2 * spread + 1)) - spread; }

 private:
  std::uint64_t s_;
};

// The device's geometry: 25 frames per set over one period, whole 0.004° steps.
FringeSetGeometry geometry(double period, double start) {
  FringeSetGeometry g{period, {}};
  for (int k = 0; k < kFrames; ++k)
    g.stage_deg.push_back(start + std::round(period * k / kFrames / 0.004) * 0.004);
  return g;
}

// Φ of the high set at a pixel, in binary-angle units: a ramp over 8.8 periods
// with a dark band (low modulation) and a bright one (saturation) across it.
std::int64_t phaseHigh(int x, int y) {
  const std::int64_t t = x + static_cast<std::int64_t>(kWidth) * y;
  return 3277 + t * 88 * 65536 / (10 * kWidth * kHeight);
}

cv::Mat frame(FringeSet set, const FringeSetGeometry& g, int k, Xorshift& rng) {
  const auto delta = static_cast<std::int64_t>(std::llround(
      65536.0 * (g.stage_deg[static_cast<std::size_t>(k)] - g.stage_deg[0]) / g.period_deg));
  cv::Mat img(kHeight, kWidth, CV_16UC1);
  const int full = (1 << kBitDepth) - 1;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      std::int64_t phi = phaseHigh(x, y);
      if (set == FringeSet::Low) phi = phi * 8 / 9;  // θh/θl = 5/5.625
      const int a = 1800;
      const int b = x < 20 ? 20 : (x >= 300 ? 2600 : 1200);  // dark | bright | normal
      const std::int32_t c = sinQ15(static_cast<std::uint32_t>(phi - delta + 16384));  // cos
      const std::int64_t v = a + (static_cast<std::int64_t>(b) * c) / 32768 + rng.noise(6);
      img.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(v < 0 ? 0 : (v > full ? full : v));
    }
  }
  return img;
}

// A calibration made of integer-derived float32 coefficients (exact), about
// the scan's phases: its evaluation is float32 Horner, as in the device.
QuasiCalibration calibration(const cv::Mat& fused) {
  const cv::Size size(kWidth, kHeight);
  std::vector<std::uint8_t> valid(size.area(), 1);
  std::vector<PixelPolynomial> pixels(size.area());
  Xorshift rng(77);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * kWidth + x;
      PixelPolynomial& p = pixels[i];
      const float f = fused.at<float>(y, x);
      p.phase_centre = f == f ? std::round(f * 64.0f) / 64.0f : 0.0f;
      p.phase_inv_half = 0.5f;
      for (int c = 0; c < 4; ++c) {
        p.x[c] = static_cast<float>(rng.noise(4096)) / 256.0f;
        p.y[c] = static_cast<float>(rng.noise(4096)) / 256.0f;
        p.z[c] = 400.0f / static_cast<float>(1 << (2 * c)) +
                 static_cast<float>(rng.noise(512)) / 1024.0f;
      }
      if ((x + y) % 97 == 0) valid[i] = 0;
    }
  }
  QuasiCalibrationInfo info;
  info.phase_source = PhaseSource::Fused;
  info.pose_count = 5;
  info.min_poses = 4;
  return QuasiCalibration(size, std::move(valid), std::move(pixels), info);
}

std::map<std::string, std::string> compute() {
  std::map<std::string, std::string> out;
  const FringeSetGeometry high = geometry(5.0, -90.0);
  const FringeSetGeometry low = geometry(5.625, 87.0);
  PhaseOptions options;
  options.bit_depth = kBitDepth;
  PhaseEngine engine(cv::Size(kWidth, kHeight), high, low, options);

  Xorshift rng(2024);
  Digest input;
  for (FringeSet set : {FringeSet::High, FringeSet::Low}) {
    const FringeSetGeometry& g = set == FringeSet::High ? high : low;
    for (int k = 0; k < kFrames; ++k) {
      const cv::Mat f = frame(set, g, k, rng);
      input.add(f);
      engine.fold(set, k, f);
    }
  }
  out["input.frames"] = input.hex();

  CompactPhase compact;
  engine.finalizeCompact(compact);
  out["compact.absolute"] = digestOf(compact.absolute);
  out["compact.fused"] = digestOf(compact.fused);
  out["compact.invalid"] = digestOf(compact.invalid);
  out["compact.texture"] = digestOf(compact.texture);

  const PhaseMaps maps = engine.finalize();
  out["maps.wrapped_high"] = digestOf(maps.wrapped_high);
  out["maps.wrapped_low"] = digestOf(maps.wrapped_low);
  out["maps.modulation_high"] = digestOf(maps.modulation_high);
  out["maps.modulation_low"] = digestOf(maps.modulation_low);
  out["maps.texture"] = digestOf(maps.texture);
  out["maps.fringe_order"] = digestOf(maps.fringe_order);
  out["maps.absolute"] = digestOf(maps.absolute);
  out["maps.fused"] = digestOf(maps.fused);
  out["maps.invalid"] = digestOf(maps.invalid);

  const QuasiCalibration cal = calibration(maps.fused);
  out["reconstruction.xyz"] = digestOf(cal.evaluate(maps.fused));
  out["reconstruction.depth"] = digestOf(cal.evaluateDepth(maps.fused));
  const std::vector<std::byte> bytes = cal.serialize();
  Digest file;
  file.add(bytes.data(), bytes.size());
  out["calibration.file"] = file.hex();

  // Guard against a degenerate scan whose maps would all agree trivially.
  if (maps.valid_fraction < 0.5 || maps.valid_fraction > 0.99)
    throw std::runtime_error("the synthetic scan's valid fraction is " +
                             std::to_string(maps.valid_fraction) +
                             ": expected its dark and bright bands invalid, the rest valid");
  return out;
}

std::map<std::string, std::string> readDigests(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::map<std::string, std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string name, value;
    if (s >> name >> value) out[name] = value;
  }
  if (out.empty()) throw std::runtime_error(path + " holds no digests");
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::string expect;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--expect" && i + 1 < argc) {
        expect = argv[++i];
      } else {
        std::fprintf(stderr, "usage: %s [--expect FILE]\n", argv[0]);
        return 2;
      }
    }
    const auto got = compute();
    if (expect.empty()) {
      for (const auto& [name, value] : got)
        std::printf("%s %s\n", name.c_str(), value.c_str());
      return 0;
    }
    const auto want = readDigests(expect);
    int passed = 0, failed = 0;
    for (const auto& [name, value] : want) {
      const auto it = got.find(name);
      if (it != got.end() && it->second == value) {
        ++passed;
        continue;
      }
      ++failed;
      std::printf("DIFFERS %s: expected %s, got %s\n", name.c_str(), value.c_str(),
                  it == got.end() ? "(not computed)" : it->second.c_str());
    }
    for (const auto& [name, value] : got) {
      if (want.count(name) == 0) {
        ++failed;
        std::printf("DIFFERS %s: not in %s\n", name.c_str(), expect.c_str());
      }
    }
    std::printf("bit identity: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cylscan_bit_identity: %s\n", e.what());
    return 1;
  }
}
