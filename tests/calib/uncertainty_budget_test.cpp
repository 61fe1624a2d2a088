// SPDX-License-Identifier: Apache-2.0
#include "algo/uncertainty_budget.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include <gtest/gtest.h>

namespace cylscan::algo {
namespace {

// The inputs of the paper's Table "Summary of the uncertainty budget".
UncertaintyInputs papersInputs() {
  UncertaintyInputs in;
  in.repeatability_std_mm = 0.018;
  in.repeatability_count = 5;
  in.reproducibility_std_mm = 0.049;
  in.reproducibility_count = 10;
  in.reference_tolerance_mm = 0.051;
  in.calibration_rmse_mm = 0.085;
  in.sensitivity_mm_per_rad = 39.304;
  in.period_deg = 5.0;
  in.stage_resolution_deg = 0.004;
  return in;
}

TEST(UncertaintyBudget, ReproducesThePapersComponents) {
  const UncertaintyBudget b = computeUncertaintyBudget(papersInputs());
  EXPECT_NEAR(b.u_rep, 0.008, 0.0005);
  EXPECT_NEAR(b.u_repr, 0.015, 0.0005);
  EXPECT_NEAR(b.u_ref, 0.029, 0.0005);
  EXPECT_NEAR(b.u_cal, 0.085, 0.0005);
  EXPECT_NEAR(b.u_stage, 0.057, 0.0005);
  EXPECT_NEAR(b.effective_depth_resolution_mm, 0.198, 0.0005);
  EXPECT_NEAR(b.combined, 0.108, 0.0005);
  // Unrounded components give U = 0.21587 (0.216 to 3 decimals); see below.
  EXPECT_NEAR(b.expanded, 0.21587, 0.00001);
}

TEST(UncertaintyBudget, ReproducesThePapersTableFromRoundedComponents) {
  // The paper combined its printed (rounded) components: √(0.008² + 0.015² +
  // 0.029² + 0.085² + 0.057²) = 0.10772 → U = 0.21544 = 0.215.
  UncertaintyInputs in = papersInputs();
  in.component_rounding_mm = 0.001;
  const UncertaintyBudget b = computeUncertaintyBudget(in);
  EXPECT_DOUBLE_EQ(b.u_rep, 0.008);
  EXPECT_DOUBLE_EQ(b.u_repr, 0.015);
  EXPECT_DOUBLE_EQ(b.u_ref, 0.029);
  EXPECT_DOUBLE_EQ(b.u_cal, 0.085);
  EXPECT_DOUBLE_EQ(b.u_stage, 0.057);
  EXPECT_NEAR(b.combined, 0.108, 0.0005);
  EXPECT_NEAR(b.expanded, 0.215, 0.0005);
  std::printf(
      "budget: u_rep %.3f u_repr %.3f u_ref %.3f u_cal %.3f u_stage %.3f u_c %.3f U %.3f dZ %.3f\n",
      b.u_rep, b.u_repr, b.u_ref, b.u_cal, b.u_stage, b.combined, b.expanded,
      b.effective_depth_resolution_mm);
  EXPECT_NEAR(b.effective_depth_resolution_mm, 0.198, 0.0005);
}

TEST(UncertaintyBudget, StageTermUsesRadiansConsistently) {
  // S·(2π/θh)·Δα: the unit of the angles cancels, so 1 mm/rad, θh = 360° and
  // Δα = 360° give ΔZ = 2π mm.
  UncertaintyInputs in;
  in.sensitivity_mm_per_rad = 1.0;
  in.period_deg = 360.0;
  in.stage_resolution_deg = 360.0;
  const UncertaintyBudget b = computeUncertaintyBudget(in);
  EXPECT_NEAR(b.effective_depth_resolution_mm, 2 * std::numbers::pi, 1e-12);
  EXPECT_NEAR(b.u_stage, 2 * std::numbers::pi / std::sqrt(12.0), 1e-12);
}

TEST(UncertaintyBudget, RejectsBadInputs) {
  UncertaintyInputs in = papersInputs();
  in.repeatability_count = 0;
  EXPECT_THROW(computeUncertaintyBudget(in), std::invalid_argument);
  in = papersInputs();
  in.period_deg = 0.0;
  EXPECT_THROW(computeUncertaintyBudget(in), std::invalid_argument);
  in = papersInputs();
  in.calibration_rmse_mm = -1.0;
  EXPECT_THROW(computeUncertaintyBudget(in), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::algo
