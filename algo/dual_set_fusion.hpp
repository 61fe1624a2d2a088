// SPDX-License-Identifier: Apache-2.0
// Dual-set fusion: both sets measure the same projector azimuth, so ρ·Φl with
// ρ = θl/θh is a second estimate of Φh. Each is weighted by its inverse noise
// variance: var(Φh) = gh·σ²/Bh² and var(ρ·Φl) = ρ²·gl·σ²/Bl², with g the set's
// noise gain (2/N for N even shifts, see ShiftWeights::noiseGain). Hence
//   Φ = Φh + f·(ρ·Φl − Φh),   f = γ·Bl² / (γ·Bl² + Bh²),   γ = gh / (gl·ρ²).
// For equal B and N and ρ = 1.125: f = 0.441 and the RMS noise drops to
// 1/sqrt(1 + 1/ρ²) = 0.747 of Φh's (25 % lower).
#pragma once

#include <cstdint>

namespace cylscan::algo {

// Constants of the fixed-point form; every operation on them is an IEEE-754
// basic operation in float, so the result is the same bits on every IEEE CPU.
struct FixedFusionParams {
  float low_to_high = 1;  // ρ
  float gamma = 1;        // γ
  float seam = 0;         // the equivalent period in high binary-angle units (R·65536)
  std::int32_t low_to_high_q10 = 1024;  // ρ·2^10, only to decide the wrap at the seam
  std::int32_t half_seam = 0;           // seam / 2 in high binary-angle units
};

// Fused Φ in high binary-angle units (2^-16 turn of the high period) from the two
// absolute phases in their own binary-angle units and the two modulation codes
// (any common scale), absolute_low in [0, 2^21). Differences across the seam of the
// equivalent period wrap.
inline float fuseFixed(const FixedFusionParams& p, std::int32_t absolute_high,
                       std::int32_t absolute_low, std::uint32_t modulation_high,
                       std::uint32_t modulation_low) {
  // Both codes 0: take Φh alone (an integer guard keeps the division defined).
  const std::uint32_t guard = static_cast<std::uint32_t>((modulation_high | modulation_low) == 0);
  const float mh = static_cast<float>(static_cast<std::int32_t>(modulation_high | guard));
  const float ml = static_cast<float>(static_cast<std::int32_t>(modulation_low));
  const float weight_low = p.gamma * (ml * ml);
  const float fraction = weight_low / (weight_low + mh * mh);
  const float high = static_cast<float>(absolute_high);
  float difference = p.low_to_high * static_cast<float>(absolute_low) - high;
  // Across the seam the difference is about ±seam: decide that in integers (an
  // integer compare and a product with -1, 0 or 1 keep loops vectorisable).
  const std::int32_t rough = ((absolute_low * p.low_to_high_q10) >> 10) - absolute_high;
  const std::int32_t wraps = static_cast<std::int32_t>(rough > p.half_seam) -
                             static_cast<std::int32_t>(rough < -p.half_seam);
  difference -= p.seam * static_cast<float>(wraps);
  return high + fraction * difference;
}

class DualSetFusion {
 public:
  DualSetFusion(double period_high_deg, double period_low_deg, double noise_gain_high,
                double noise_gain_low, double equivalent_period_in_high_periods);

  double lowToHigh() const { return low_to_high_; }  // ρ = θl/θh
  double gamma() const { return gamma_; }
  // Weight of the low estimate, f.
  double lowFraction(double modulation_high, double modulation_low) const;
  // Fused Φ in radians of the high set, from Φh and Φl in radians of their own sets.
  double fuse(double absolute_high_rad, double absolute_low_rad, double modulation_high,
              double modulation_low) const;
  // Theoretical RMS of the fused Φ over that of Φh alone.
  double expectedNoiseRatio(double modulation_high, double modulation_low) const;

  const FixedFusionParams& fixedParams() const { return fixed_; }

 private:
  double low_to_high_, gamma_, seam_rad_;
  FixedFusionParams fixed_;
};

}  // namespace cylscan::algo
