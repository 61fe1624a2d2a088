// SPDX-License-Identifier: Apache-2.0
#include "algo/uncertainty_budget.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cylscan::algo {
namespace {

double radians(double degrees) {
  return degrees * std::numbers::pi / 180.0;
}

}  // namespace

UncertaintyBudget computeUncertaintyBudget(const UncertaintyInputs& in) {
  if (in.repeatability_count < 1 || in.reproducibility_count < 1)
    throw std::invalid_argument("uncertainty budget: repeat and pose counts must be >= 1");
  if (in.repeatability_std_mm < 0.0 || in.reproducibility_std_mm < 0.0 ||
      in.reference_tolerance_mm < 0.0 || in.calibration_rmse_mm < 0.0 ||
      in.sensitivity_mm_per_rad < 0.0 || in.stage_resolution_deg < 0.0 ||
      in.coverage_factor <= 0.0 || in.component_rounding_mm < 0.0)
    throw std::invalid_argument("uncertainty budget: inputs must be non-negative");
  if (!(in.period_deg > 0.0))
    throw std::invalid_argument("uncertainty budget: the period θh must be > 0");

  UncertaintyBudget b;
  b.u_rep = in.repeatability_std_mm / std::sqrt(static_cast<double>(in.repeatability_count));
  b.u_repr = in.reproducibility_std_mm / std::sqrt(static_cast<double>(in.reproducibility_count));
  b.u_ref = in.reference_tolerance_mm / std::sqrt(3.0);
  b.u_cal = in.calibration_rmse_mm;
  // |∂Φ/∂α| = 2π/θh (rad of phase per rad of stage), times Δα in rad.
  const double phase_per_stage = 2.0 * std::numbers::pi / radians(in.period_deg);
  b.effective_depth_resolution_mm =
      in.sensitivity_mm_per_rad * phase_per_stage * radians(in.stage_resolution_deg);
  b.u_stage = b.effective_depth_resolution_mm / std::sqrt(12.0);

  if (in.component_rounding_mm > 0.0) {
    const double step = in.component_rounding_mm;
    for (double* u : {&b.u_rep, &b.u_repr, &b.u_ref, &b.u_cal, &b.u_stage})
      *u = std::round(*u / step) * step;
  }
  b.combined = std::sqrt(b.u_rep * b.u_rep + b.u_repr * b.u_repr + b.u_ref * b.u_ref +
                         b.u_cal * b.u_cal + b.u_stage * b.u_stage);
  b.expanded = in.coverage_factor * b.combined;
  return b;
}

}  // namespace cylscan::algo
