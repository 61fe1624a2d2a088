// SPDX-License-Identifier: Apache-2.0
// Two-wavelength temporal phase unwrapping (paper Eqs. 6-8, in the phase
// convention of docs/formats.md, capture bundle).
//
// Both sets measure the same projector azimuth and are zero at the same azimuth.
// With φeq = (φh − φl) mod 2π and the ratio R = λeq/λh = θl/(θl − θh),
//   K  = round((R·φeq − φh) / 2π)   (mod the number of orders),   Φ = φh + 2πK,
// and the residual R·φeq − φh − 2πK is the order-consistency measure. The low set
// unwraps the same way with R − 1 = θh/(θl − θh); since R·φeq − φh and
// (R − 1)·φeq − φl differ by exactly 2π·[φh < φl], its order is K − [φh < φl].
// For θh = 5°, θl = 5.625°: R = 9 and R − 1 = 8, both exact.
#pragma once

#include <cstdint>

#include "algo/binary_angle.hpp"

namespace cylscan::algo {

// Integer form of the unwrapper: binary angles in, orders and a residual out.
struct FixedUnwrapParams {
  std::int32_t ratio_q = 0;  // R · 2^shift, exact when R·2^shift is an integer (R = 9: 9·2^11)
  int shift = 0;             // residual unit: 2^-(16 + shift) turn
  std::int32_t orders_high = 1;
  std::int32_t orders_low = 1;
  // The centre the residual is taken about (algo/order_residual.hpp), in the
  // residual's unit, in [−1, 1) turn: 0 for sets exactly in phase; beyond
  // ±1/2 turn when it is taken near a calibration's centre.
  std::int32_t residual_centre = 0;
};

struct FixedOrders {
  std::int32_t high = 0;  // K of the high set, in [0, orders_high)
  std::int32_t low = 0;   // K of the low set, in [0, orders_low)
  // R·φeq − φh − 2πK − centre in units of 2^-(16+shift) turn, [-1/2, 1/2) turn
  std::int32_t residual = 0;
};

// All integer, no branches (selects), no overflow: (R + 3.5)·2^(16+shift) < 2^31.
inline FixedOrders unwrapFixed(const FixedUnwrapParams& p, BinaryAngle phi_high,
                               BinaryAngle phi_low) {
  const int bits = 16 + p.shift;
  const std::int32_t unit = std::int32_t{1} << bits;
  const std::int32_t half = unit >> 1;
  const auto h = static_cast<std::int32_t>(phi_high);
  const auto equivalent = static_cast<std::int32_t>(static_cast<BinaryAngle>(phi_high - phi_low));
  // In (−2, R + 1) turns: R·φeq − φh is in (−1, R), the centre in [−1, 1).
  const std::int32_t x =
      equivalent * p.ratio_q - h * (std::int32_t{1} << p.shift) - p.residual_centre;
  const std::int32_t biased = x + 2 * unit + half;  // > 0: shifts below act on non-negative values
  const std::int32_t raw = (biased >> bits) - 2;    // round(x / unit) in [-2, R + 1]
  FixedOrders out;
  out.residual = (biased & (unit - 1)) - half;
  // raw is in [−2, R + 1] and orders_high = ceil(R) ≥ 2, so one add and one
  // subtract bring K into [0, orders_high). The low order raw − [φh < φl] is in
  // [−3, R + 1] with orders_low = ceil(R − 1) ≥ 1: three of each cover it.
  // The corrections are masks, not selects: a chain of selects on one value
  // is threaded by the compiler into branches that its vectoriser gives up on.
  const auto all_if = [](bool c) { return -static_cast<std::int32_t>(c); };
  const std::int32_t k = raw + (p.orders_high & all_if(raw < 0));
  out.high = k - (p.orders_high & all_if(k >= p.orders_high));
  std::int32_t kl = raw - static_cast<std::int32_t>(phi_high < phi_low);
  for (int i = 0; i < 3; ++i)
    kl += p.orders_low & all_if(kl < 0);
  for (int i = 0; i < 3; ++i)
    kl -= p.orders_low & all_if(kl >= p.orders_low);
  out.low = kl;
  return out;
}

// Orders from the double-precision reference.
struct ReferenceOrders {
  int high = 0;
  int low = 0;
  double residual_rad = 0;  // R·φeq − φh − 2πK − centre, in [-π, π)
};

class TwoWavelengthUnwrapper {
 public:
  // Largest supported R = θl/(θl − θh) (periods closer than 1/65 apart are not supported).
  static constexpr double kMaxRatio = 64;

  // Throws std::invalid_argument unless 0 < θh < θl and R <= kMaxRatio.
  TwoWavelengthUnwrapper(double period_high_deg, double period_low_deg);

  double ratioHigh() const { return ratio_high_; }     // λeq/λh = θl/(θl − θh)
  double ratioLow() const { return ratio_high_ - 1; }  // λeq/λl = θh/(θl − θh)
  double equivalentPeriodDeg() const { return period_high_deg_ * ratio_high_; }
  double periodHighDeg() const { return period_high_deg_; }
  double periodLowDeg() const { return period_low_deg_; }
  // Distinct fringe orders: R and R − 1 rounded up. With a non-integer R the two
  // patterns do not repeat together, so K wraps only approximately at the seam.
  int ordersHigh() const { return params_.orders_high; }
  int ordersLow() const { return params_.orders_low; }
  bool ratioIsInteger() const { return ratio_is_integer_; }

  // `centre_rad`: the centre the residual is taken about (algo/order_residual.hpp).
  ReferenceOrders unwrap(double phi_high_rad, double phi_low_rad, double centre_rad = 0) const;

  const FixedUnwrapParams& fixedParams() const { return params_; }
  FixedOrders unwrap(BinaryAngle phi_high, BinaryAngle phi_low) const {
    return unwrapFixed(params_, phi_high, phi_low);
  }
  // A residual bound in radians as the integer bound of FixedOrders::residual.
  std::int32_t fixedResidualBound(double bound_rad) const;
  double fixedResidualToRadians(std::int32_t residual) const;

 private:
  double period_high_deg_, period_low_deg_;
  double ratio_high_;
  bool ratio_is_integer_;
  FixedUnwrapParams params_;
};

}  // namespace cylscan::algo
