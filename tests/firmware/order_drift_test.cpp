// SPDX-License-Identifier: Apache-2.0
#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "firmware/reconstruction.hpp"

namespace cylscan::firmware {
namespace {

using ::testing::HasSubstr;

algo::OrderResidual scanAt(double centre_rad) {
  algo::OrderResidual r;
  r.centre_rad = centre_rad;
  r.spread_rad = 0.05;
  r.bound_rad = std::numbers::pi / 2;
  r.samples = 8000;
  return r;
}

algo::QuasiCalibrationInfo calibratedAt(float centre_rad) {
  algo::QuasiCalibrationInfo info;
  info.order_centre_rad = centre_rad;
  info.order_spread_rad = 0.05f;
  return info;
}

TEST(OrderDrift, ASmallDriftIsQuiet) {
  EXPECT_FALSE(orderDriftWarning("main", scanAt(1.0 + 0.7), calibratedAt(1.0f)));
  EXPECT_FALSE(orderDriftWarning("main", scanAt(1.0 - 0.7), calibratedAt(1.0f)));
}

TEST(OrderDrift, ALargerDriftWarnsAndNamesTheCauses) {
  const std::optional<std::string> warning =
      orderDriftWarning("aux", scanAt(1.0 + 0.9), calibratedAt(1.0f));
  ASSERT_TRUE(warning);
  EXPECT_THAT(*warning, HasSubstr("aux"));
  EXPECT_THAT(*warning, HasSubstr("0.9"));
  EXPECT_THAT(*warning, HasSubstr("start angles"));
  EXPECT_THAT(*warning, HasSubstr("steps lost"));
  EXPECT_THAT(*warning, HasSubstr("backlash"));
  EXPECT_THAT(*warning, HasSubstr("calibrate again"));
}

// A scan tied to a centre near π reports it beyond π (the reference plus the
// wrapped difference): that is no drift. The difference is taken on the circle.
TEST(OrderDrift, TheDriftIsTakenOnTheCircle) {
  EXPECT_FALSE(orderDriftWarning("main", scanAt(3.2), calibratedAt(3.1f)));
  EXPECT_FALSE(orderDriftWarning("main", scanAt(-3.1), calibratedAt(3.1f)));
  EXPECT_TRUE(orderDriftWarning("main", scanAt(-2.0), calibratedAt(3.1f)));
}

TEST(OrderDrift, UnknownCentresNeverWarn) {
  EXPECT_FALSE(orderDriftWarning("main", scanAt(2.5), algo::QuasiCalibrationInfo{}));
  algo::OrderResidual unmeasured = scanAt(2.5);
  unmeasured.samples = 0;
  EXPECT_FALSE(orderDriftWarning("main", unmeasured, calibratedAt(0.0f)));
  EXPECT_FALSE(orderReference(algo::QuasiCalibrationInfo{}));
  EXPECT_EQ(orderReference(calibratedAt(-1.5f)), -1.5);
}

}  // namespace
}  // namespace cylscan::firmware
