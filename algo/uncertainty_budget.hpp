// SPDX-License-Identifier: Apache-2.0
// The paper's GUM uncertainty budget of the reconstructed depth ("Measurement
// uncertainty analysis"): five independent components combined in quadrature
// and expanded with k = 2.
#pragma once

namespace cylscan::algo {

struct UncertaintyInputs {
  double repeatability_std_mm = 0.0;    // s of the RMSE over n repeats (Type A)
  int repeatability_count = 1;          // n
  double reproducibility_std_mm = 0.0;  // s of the pose-wise RMSE over m poses (Type A)
  int reproducibility_count = 1;        // m
  double reference_tolerance_mm =
      0.0;                           // ± half-width of the artifact's tolerance (uniform, Type B)
  double calibration_rmse_mm = 0.0;  // pooled RMSE σ_cal of Eq. (12) (Type A)
  double sensitivity_mm_per_rad = 0.0;  // S_eff = <|∂Z/∂Φ|>
  double period_deg = 5.0;              // θh: stage rotation for one phase period 2π
  double stage_resolution_deg = 0.0;    // Δα
  double coverage_factor = 2.0;         // k
  // 0: combine the components as computed. > 0: round each component to this
  // step (e.g. 0.001 mm) before combining, the way the paper's table was
  // combined from its printed values.
  double component_rounding_mm = 0.0;
};

struct UncertaintyBudget {
  double u_rep = 0.0;                          // s/√n
  double u_repr = 0.0;                         // s/√m
  double u_ref = 0.0;                          // tolerance/√3
  double u_cal = 0.0;                          // σ_cal
  double u_stage = 0.0;                        // S_eff·(2π/θh)·Δα/√12, angles in radians
  double combined = 0.0;                       // u_c
  double expanded = 0.0;                       // U = k·u_c
  double effective_depth_resolution_mm = 0.0;  // ΔZ_eff = S_eff·(2π/θh)·Δα
};

// invalid_argument on counts < 1, negative inputs or θh ≤ 0.
UncertaintyBudget computeUncertaintyBudget(const UncertaintyInputs& inputs);

}  // namespace cylscan::algo
