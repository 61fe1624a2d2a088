// SPDX-License-Identifier: Apache-2.0
// Least-squares phase-shift weights of one fringe set (docs/formats.md, capture
// bundle: the intensity model).
//
// Frame k carries I_k = A + C cos δk + S sin δk with C = B cos φ, S = B sin φ.
// With rows r_k = [1, cos δk, sin δk] and the normal matrix M = Σ r_k r_kᵀ (the
// same for every pixel), the per-frame weights w_k = M⁻¹ r_k give
// (A, C, S) = Σ_k w_k I_k. For N equal shifts over one period this is the
// paper's Eq. (4) in the sign convention of the bundle's intensity model.
#pragma once

#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "algo/fringe_set.hpp"

namespace cylscan::algo {

// Thrown for shift sets that cannot be solved; the message names the set.
class ShiftSolveError : public std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// The weights of one frame for the three unknowns.
struct FrameWeights {
  double a = 0;  // for A (the texture)
  double c = 0;  // for C = B cos φ
  double s = 0;  // for S = B sin φ
};

class ShiftWeights {
 public:
  // Above this the normal matrix is rejected as ill-conditioned: the phase noise
  // would be amplified by about sqrt(cond) against a full, even period.
  static constexpr double kMaxConditionNumber = 1e4;

  // Shifts from the executed stage angles: δk = 2π·(stage_deg[k] − stage_deg[0]) / period_deg.
  // Throws ShiftSolveError naming `set_name` for < 3 frames, non-finite angles, a bad
  // period or a singular / ill-conditioned normal matrix.
  ShiftWeights(const FringeSetGeometry& geometry, std::string_view set_name);

  // Shifts given directly, as fractions of a turn (δk = 2π·turns[k]).
  static ShiftWeights fromTurns(std::span<const double> turns, std::string_view set_name);

  std::size_t frameCount() const { return frames_.size(); }
  const FrameWeights& frame(std::size_t k) const { return frames_.at(k); }
  std::span<const FrameWeights> frames() const { return frames_; }
  // δk in radians, in [0, 2π).
  std::span<const double> shiftsRad() const { return shifts_rad_; }
  // cos δk and sin δk as used for the weights (computed with a reproducible
  // polynomial, so the weights are the same bits on every IEEE-754 CPU).
  double cosShift(std::size_t k) const { return cos_.at(k); }
  double sinShift(std::size_t k) const { return sin_.at(k); }

  // 2-norm condition number of M: 1.5 … 2 for a full even period, large for a short arc.
  double conditionNumber() const { return condition_number_; }
  // Phase-noise gain averaged over φ: var(φ) = gain · σ_I² / B² (2/N for N even shifts).
  double noiseGain() const { return noise_gain_; }
  const std::string& setName() const { return set_name_; }

 private:
  ShiftWeights(std::vector<double> turns, std::string_view set_name);

  std::string set_name_;
  std::vector<FrameWeights> frames_;
  std::vector<double> shifts_rad_, cos_, sin_;
  double condition_number_ = 0;
  double noise_gain_ = 0;
};

// cos(2πt) and sin(2πt) from + − × / and floor only, in a fixed order, so the
// result is the same bits on every IEEE-754 CPU (libm's last bit may differ).
// Accurate to about 1 ulp.
struct CosSin {
  double cos = 1;
  double sin = 0;
};
CosSin reproducibleCosSinOfTurns(double turns);

}  // namespace cylscan::algo
