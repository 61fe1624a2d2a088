// SPDX-License-Identifier: Apache-2.0
// What the order residual r = R·φeq − φh − 2πK says about a whole scan.
//
// On a real head the two sets are never exactly in phase: the cylinder's two
// slot halves are misaligned by a fraction of a degree, and the home switch and
// the start angles add their own offset. An offset δ of the low set moves every
// pixel's residual by −R·δ (about 10 rad per degree of misalignment at θl =
// 5.625°, R = 9), so the residuals gather around a centre that may be anywhere
// on the circle. Unwrapping around that centre instead of zero gives every
// pixel its order again; the centre is only known modulo 2π, which shifts all
// orders by one constant integer for a given head and leaves Φ consistent
// between its scans.
//
// The spread of the residuals about the centre (noise, harmonics, gamma, all
// multiplied by R) then sets the bound beyond which a pixel's order is not
// trusted. Everything here is integer so that it gives the same bits on every CPU.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace cylscan::algo {

// Residuals in the unit of FixedOrders::residual: 2^bits per turn (2π), each in
// [−2^(bits−1), 2^(bits−1)).
struct ResidualStatistics {
  std::int32_t centre = 0;  // the residuals' circular centre
  std::int32_t spread = 0;  // robust σ about it: 1.4826 · median |r − centre|
  std::size_t samples = 0;  // residuals it was measured on
  // The residuals' reach: the 99.9th percentile of |r − centre|.
  std::int32_t reach = 0;
  // Residuals within 1/16 turn of the antipode centre ± π, where a pixel is
  // nearly as close to the next order as to its own.
  std::size_t near_antipode = 0;
};

// At most one residual in this many may lie near the antipode for the gap
// rule of residualBound to apply: 4 of the engine's ~8k samples, what 0.4 %
// of pixels with random phases (edges, shadows: 1/8 of them land there) give.
inline constexpr std::size_t kAntipodeSamplesPerOutlier = 2048;

// The fewest residuals a centre is measured from; with fewer, centre and
// spread are 0 and the caller keeps its defaults.
inline constexpr std::size_t kMinResidualSamples = 256;

// The centre is the peak of a 64-bin circular histogram (smoothed 1-2-1), then
// the mean of the residuals within ±1/8 turn of it, re-centred; the spread is the
// scaled median absolute deviation about the centre, robust to the half of the
// pixels that may be wrong (edges, shadows). `residuals` is reordered.
ResidualStatistics measureResiduals(std::span<std::int32_t> residuals, int bits);

// The residual bound that follows from a spread σ: min(6σ, 2π − 4.5σ) within
// [π/2, 0.9π].
// - 6σ: a residual farther out does not come from the scan's noise (Gaussian
//   tail 2e-9) but from a pixel whose phases disagree (a depth edge, a
//   reflection), whose order is in doubt.
// - 2π − 4.5σ: a wrong order is accepted only when the phase error exceeds
//   2π − bound, which then is at least 4.5σ (two-sided tail 7e-6).
// - π/2 below: a clean scan (σ of a few mrad) keeps the classic bound rather
//   than rejecting the small systematic errors of quantisation and harmonics.
// - 0.9π above: a residual near ±π is equally near two orders.
std::int32_t residualBoundForSpread(std::int32_t spread, int bits);

// The bound the engine uses: the larger of the spread's bound and, when the
// residuals leave the antipode empty, one in the middle of that gap (halfway
// from their reach to ±π), within [π/2, 0.9π].
// The spread's rule assumes Gaussian tails. The harmonics of a blurred
// square wave and a camera's gamma at N = 3 or 4 instead give a bounded error,
// a sum of sinusoids of the phase: its MAD is large (σ ≈ 1 rad at N = 3,
// γ = 0.45, R = 8) but it never reaches ±π, so no order is wrong, and the
// spread's bound would reject a fifth of the pixels whose orders are all
// right. A wrong order needs a phase error beyond π, which would show as
// residuals near the antipode (an error between π and 9π/8 lands there); with
// none there, the orders up to the gap are right.
std::int32_t residualBound(const ResidualStatistics& stats, int bits);

// x wrapped into [−2^(bits−1), 2^(bits−1)).
constexpr std::int32_t wrapResidual(std::int64_t x, int bits) {
  const std::int64_t unit = std::int64_t{1} << bits;
  const std::int64_t half = unit >> 1;
  return static_cast<std::int32_t>(((x + half) & (unit - 1)) - half);
}

}  // namespace cylscan::algo
