// SPDX-License-Identifier: Apache-2.0
// The ring planner of the 360° head (docs/head-360.md): every camera's working volume
// inside one equivalent period at its sets' first frames and off the half
// boundaries during its sweeps; a common frame step whose shifts are well
// conditioned for both sets; impossible layouts refused naming the camera.
//
// The checks recompute the wall angles from the chosen start with the
// convention of the projector (β = a − ρ; high slots on [h0, h0 + 180)), so a
// planner that picked a bad start would fail them.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "drivers/stage_config.hpp"
#include "firmware/scan_plan.hpp"

namespace cylscan::firmware {
namespace {

// The paper's camera (board/sim's main, 540–620 mm) spans these azimuths; the
// 360° head's cameras are it turned by 0, 90, 180 and 270 degrees.
constexpr double kMainLo = -20.15;
constexpr double kMainHi = -2.88;

ScanOptions ringOptions(const std::vector<std::pair<std::string, double>>& cameras) {
  ScanOptions o;
  o.plan = firmware::PlanKind::Ring;
  o.frames_high = o.frames_low = 25;
  o.cameras.clear();
  for (const auto& [name, turn] : cameras) {
    o.cameras.push_back(name);
    o.azimuths.push_back({name, kMainLo + turn, kMainHi + turn});
  }
  return o;
}

ScanOptions fourCameras() {
  return ringOptions({{"main", 0}, {"cam90", 90}, {"cam180", 180}, {"cam270", 270}});
}

double wrap360(double a) {
  return a - 360.0 * std::floor(a / 360.0);
}

// True when no point origin + k·spacing lies in [lo, hi] (or within `margin` of it).
bool clearOfGrid(double lo, double hi, double origin, double spacing, double margin) {
  for (int k = -20; k <= 20; ++k) {
    const double g = origin + k * spacing;
    if (g >= lo - margin && g <= hi + margin) return false;
  }
  return true;
}

TEST(RingPlan, EveryCameraInsideOneEquivalentPeriodAndOffTheHalfBoundaries) {
  const ScanOptions o = fourCameras();
  const drivers::StageConfig stage;
  const ScanPlan plan = planScan(o, stage);
  ASSERT_TRUE(plan.ring.has_value());
  const RingLayout& ring = *plan.ring;
  const double spd = stage.stepsPerDeg();
  ASSERT_EQ(plan.high.positions.size(), 25u);
  ASSERT_EQ(plan.low.positions.size(), 25u);
  // Sweep 2 is sweep 1 turned by half a turn, in the same steps.
  EXPECT_EQ(std::llabs(plan.low.positions.front() - plan.high.positions.front()),
            std::llround(180.0 * spd));
  for (std::size_t k = 1; k < 25; ++k) {
    EXPECT_EQ(plan.high.positions[k] - plan.high.positions[k - 1], ring.step_steps);
    EXPECT_EQ(plan.low.positions[k] - plan.low.positions[k - 1], ring.step_steps);
  }
  const double span = 24.0 * ring.step_steps / spd;
  for (const auto& az : o.azimuths) {
    SCOPED_TRACE(az.camera);
    for (const auto& sweep : {plan.high, plan.low}) {
      const double rho0 = static_cast<double>(sweep.positions.front()) / spd;
      // β over the sweep: from a − ρ0 down by the span.
      const double lo = az.lo_deg - rho0 - span, hi = az.hi_deg - rho0;
      EXPECT_TRUE(clearOfGrid(lo, hi, 0.0, 180.0, o.ring_margin_deg)) << "straddles a half";
      EXPECT_TRUE(clearOfGrid(az.lo_deg - rho0, hi, 0.0, 45.0, o.ring_margin_deg))
          << "straddles an equivalent-period wrap";
      // The set this sweep gives the camera is the half it faces.
      const FringeSet faced = wrap360(lo) < 180.0 ? FringeSet::High : FringeSet::Low;
      EXPECT_EQ(plan.setOf(az.camera, sweep.set), faced);
    }
  }
  // Main takes its high set from sweep 1; the cameras turned by 90° and 180°
  // face the low half then (their wall angles are 90° and 180° further on).
  EXPECT_EQ(plan.setOf("main", FringeSet::High), FringeSet::High);
  EXPECT_EQ(plan.setOf("cam90", FringeSet::High), FringeSet::Low);
  EXPECT_EQ(plan.setOf("cam180", FringeSet::High), FringeSet::Low);
  EXPECT_EQ(plan.setOf("cam270", FringeSet::High), FringeSet::High);
  EXPECT_EQ(plan.swapped.size(), 2u);
  for (const auto& c : ring.cameras) {
    EXPECT_GE(c.window_margin_deg, o.ring_margin_deg) << c.camera;
    EXPECT_GE(c.half_margin_deg, o.ring_margin_deg) << c.camera;
  }
}

TEST(RingPlan, CamerasGetTheirOwnSetsAnglesAndPeriods) {
  const ScanPlan plan = planScan(fourCameras(), drivers::StageConfig{});
  // A swapped camera's high set is sweep 2, and the angles are executed steps.
  EXPECT_EQ(plan.anglesDeg("cam90", FringeSet::High), plan.anglesDeg(FringeSet::Low));
  EXPECT_EQ(plan.anglesDeg("cam90", FringeSet::Low), plan.anglesDeg(FringeSet::High));
  EXPECT_EQ(plan.anglesDeg("main", FringeSet::High), plan.anglesDeg(FringeSet::High));
  EXPECT_EQ(&plan.motionSetOf("cam180", FringeSet::High), &plan.low);
  EXPECT_DOUBLE_EQ(plan.periodDeg(FringeSet::High), 5.0);
  EXPECT_DOUBLE_EQ(plan.periodDeg(FringeSet::Low), 5.625);
}

TEST(RingPlan, NoiseGainIsOneForEqualShiftsOverAPeriod) {
  for (const int n : {3, 4, 8, 25}) {
    std::vector<double> shifts;
    for (int k = 0; k < n; ++k)
      shifts.push_back(2 * std::numbers::pi * k / n);
    EXPECT_NEAR(phaseNoiseGain(shifts), 1.0, 1e-12) << n;
  }
  // All shifts alike: nothing to fit.
  EXPECT_TRUE(std::isinf(phaseNoiseGain({0.3, 0.3, 0.3, 0.3})));
  // 25 frames over 8/9 of a period (a low set stepped by θh/N) costs a little.
  std::vector<double> short_span;
  for (int k = 0; k < 25; ++k)
    short_span.push_back(2 * std::numbers::pi * k * 0.2 / 5.625);
  const double g = phaseNoiseGain(short_span);
  EXPECT_GT(g, 1.0);
  EXPECT_LT(g, 1.2);
}

TEST(RingPlan, ChosenStepIsNoWorseThanEitherSetsOwnStep) {
  const drivers::StageConfig stage;
  const ScanPlan plan = planScan(fourCameras(), stage);
  const RingLayout& ring = *plan.ring;
  const double chosen = std::max(ring.noise_gain_high, ring.noise_gain_low);
  EXPECT_LT(chosen, 1.05);
  // θh/N = 50 steps and θl/N = 56.25 steps: the worse set's gain with each.
  for (const double step_deg : {0.2, 0.225}) {
    ScanOptions o = fourCameras();
    o.step_deg = step_deg;
    const ScanPlan p = planScan(o, stage);
    EXPECT_LE(chosen, std::max(p.ring->noise_gain_high, p.ring->noise_gain_low) + 1e-12)
        << step_deg;
  }
}

TEST(RingPlan, RefusesAWorkingVolumeWiderThanAnEquivalentPeriod) {
  ScanOptions o = fourCameras();
  o.azimuths[1] = {"cam90", 60.0, 110.0};
  try {
    planScan(o, drivers::StageConfig{});
    FAIL() << "a 50° working volume was planned";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("camera 'cam90'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("equivalent period"), std::string::npos) << e.what();
  }
}

TEST(RingPlan, RefusesCamerasThatNoStartSeparates) {
  // Two volumes 1° apart, each 30° wide: a wrap would have to fall in the 1°
  // gap with 1° to spare on both sides.
  ScanOptions o;
  o.plan = firmware::PlanKind::Ring;
  o.cameras = {"main", "side"};
  o.azimuths = {{"main", 0.0, 30.0}, {"side", 31.0, 61.0}};
  try {
    planScan(o, drivers::StageConfig{});
    FAIL() << "planned an impossible layout";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no ring start"), std::string::npos) << what;
    EXPECT_TRUE(what.find("'main'") != std::string::npos ||
                what.find("'side'") != std::string::npos)
        << what;
  }
  // With the gap wide enough the same pair is planned.
  o.azimuths[1] = {"side", 34.0, 64.0};
  EXPECT_NO_THROW(planScan(o, drivers::StageConfig{}));
}

TEST(RingPlan, RefusesACameraWithoutAzimuthsAndUnequalSweeps) {
  ScanOptions o = fourCameras();
  o.azimuths.pop_back();
  try {
    planScan(o, drivers::StageConfig{});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cam270"), std::string::npos) << e.what();
  }
  o = fourCameras();
  o.frames_low = 20;
  EXPECT_THROW(planScan(o, drivers::StageConfig{}), std::invalid_argument);
  o = fourCameras();
  o.step_deg = 0.001;  // a quarter of a motor step
  EXPECT_THROW(planScan(o, drivers::StageConfig{}), std::invalid_argument);
  // A whole number of low periods between frames: every low frame alike.
  o = fourCameras();
  o.step_deg = 5.625;
  EXPECT_THROW(planScan(o, drivers::StageConfig{}), std::invalid_argument);
}

TEST(RingPlan, SetsPlanIsUnchanged) {
  ScanOptions o;  // plan = Sets
  o.high_start_deg = 235.98;
  o.low_start_deg = 55.98;
  const ScanPlan plan = planScan(o, drivers::StageConfig{});
  EXPECT_FALSE(plan.ring.has_value());
  EXPECT_TRUE(plan.swapped.empty());
  EXPECT_EQ(plan.setOf("main", FringeSet::Low), FringeSet::Low);
  EXPECT_EQ(plan.anglesDeg("aux", FringeSet::High), plan.anglesDeg(FringeSet::High));
  EXPECT_DOUBLE_EQ(plan.high.step_deg, 0.2);
}

}  // namespace
}  // namespace cylscan::firmware
