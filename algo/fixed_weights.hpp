// SPDX-License-Identifier: Apache-2.0
// Integer per-frame weights of one fringe set for the fixed-point path.
//
// C and S share one scale (atan2 is scale-invariant), chosen as large as the
// int32 sums allow: maxPixel·Σ|q_k| <= kSumLimit for q = qc and q = qs. The
// texture weights qa share one even scale across BOTH sets, because the texture
// sum runs on through the two sets and keeps the saturation flag in its LSB.
// Rounding uses largest remainders so that Σ qc = Σ qs = 0 and Σ qa = a_scale
// exactly, as for the real weights: a constant background leaks nothing into C, S.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/shift_weights.hpp"

namespace cylscan::algo {

struct FixedSetWeights {
  // Bound on any partial sum, a little under INT32_MAX; leaves the LSB flag room.
  static constexpr std::int64_t kSumLimit = 2'147'000'000;

  std::vector<std::int32_t> c, s, a;  // per frame; every a[k] is even
  double cs_scale = 0;                // integer C, S = cs_scale · (C, S in counts)
  std::int64_t a_scale = 0;           // integer A = a_scale · (A in counts), even

  std::size_t frameCount() const { return c.size(); }

  // Throws std::logic_error if the bounds cannot be met (not for valid inputs).
  static FixedSetWeights quantize(const ShiftWeights& weights, int max_pixel, std::int64_t a_scale);
  // Largest even a_scale for which the texture sum over all `sets` fits kSumLimit.
  static std::int64_t sharedTextureScale(std::span<const ShiftWeights* const> sets, int max_pixel);
};

// Rounds `values` to integers whose sum is exactly `target` (largest remainders;
// ties broken by index, so the result is reproducible). Each result is within 1 of
// its value when |target − Σ values| < 0.5.
std::vector<std::int64_t> roundToSum(std::span<const double> values, std::int64_t target);

}  // namespace cylscan::algo
