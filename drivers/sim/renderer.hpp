// SPDX-License-Identifier: Apache-2.0
// Rendering of camera frames on the virtual head. Everything that does not
// change between frames is traced once per scene and camera (PixelGeometry);
// a frame then only evaluates the projector's pattern at each pixel's wall
// angle and adds the sensor's noise.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/scene.hpp"

namespace cylscan::sim {

// Per-pixel optics of one camera looking at one scene, lit by the projector.
struct PixelGeometry {
  int width = 0, height = 0;
  std::vector<float> ambient;  // ambient · albedo (fraction of full well per reference exposure)
  std::vector<float> direct;   // projector signal with the slot fully open (0: dark/shadow/miss)
  std::vector<CylindricalProjector::RayGeometry> rays;  // projector ray of the first hit
  cv::Mat points;  // CV_64FC3 first hit in the main frame (NaN where the ray hits nothing)
  cv::Mat flags;   // CV_8U, bits below
  static constexpr std::uint8_t kHit = 1;  // the camera sees a surface
  static constexpr std::uint8_t kLit = 2;  // the projector reaches it (extent, facing, unshadowed)
  static constexpr std::uint8_t kShadow = 4;  // facing and in extent, but occluded from the source
};

struct TraceOptions {
  int supersample = 1;  // s × s rays per pixel for the lighting terms (anti-aliasing)
  int threads = 0;      // 0: up to 2
};

PixelGeometry tracePixels(const Scene& scene, const CameraModel& camera,
                          const CylindricalProjector& projector, const TraceOptions& options = {});

// splitmix64 finaliser.
inline std::uint64_t mixBits(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Standard normal samples, generated once from a seed; frames index them by a
// hash of (frame key, pixel), so noise is the same whatever the thread count.
class NoiseTable {
 public:
  explicit NoiseTable(std::uint64_t seed);
  float sample(std::uint64_t key, std::uint64_t pixel) const {
    return values_[mixBits(key ^ (pixel * 0xD1B54A32D192ED03ULL)) >> (64 - kBits)];
  }
  static constexpr int kBits = 16;  // 256 KiB: stays in the L2 cache

 private:
  std::vector<float> values_;
};

struct Exposure {
  static constexpr int kMaxSamples = 8;
  std::array<double, kMaxSamples> stage_deg{};  // stage angle at each sub-sample of the exposure
  std::array<bool, kMaxSamples> light{};        // source on at each sub-sample
  // A rolling shutter: the stage angle at each sub-sample of the last row's
  // exposure; rows between take theirs linearly (used when `rolling`).
  std::array<double, kMaxSamples> stage_deg_last_row{};
  bool rolling = false;
  double source_gain = 1.0;     // the source's level now, as a factor (LED warm-up)
  double response_gamma = 1.0;  // the sensor's response curve (CameraParams)
  int samples = 1;
  double exposure_us = 10000;
  double reference_exposure_us = 10000;
  double gain = 1.0;
  int bit_depth = 8;
  double full_well_e = 10500;
  double read_noise_e = 2.3;
  double noise_scale = 1.0;  // 0: noiseless (quantisation only)
  std::uint64_t noise_key = 0;
};

// CV_8UC1 (bit_depth 8) or CV_16UC1 (more bits, counts unscaled).
cv::Mat renderFrame(const PixelGeometry& geometry, const CylindricalProjector& projector,
                    const Exposure& exposure, const NoiseTable& noise, int threads = 0);

}  // namespace cylscan::sim
