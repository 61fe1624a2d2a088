// SPDX-License-Identifier: Apache-2.0
#include "algo/temporal_unwrapping.hpp"

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "algo/numbers.hpp"

namespace cylscan::algo {
namespace {

// k into [0, orders) for any integer k.
int wrapOrder(int k, int orders) {
  const int r = k % orders;
  return r < 0 ? r + orders : r;
}

}  // namespace

TwoWavelengthUnwrapper::TwoWavelengthUnwrapper(double period_high_deg, double period_low_deg)
    : period_high_deg_(period_high_deg), period_low_deg_(period_low_deg) {
  if (!std::isfinite(period_high_deg) || !std::isfinite(period_low_deg) || period_high_deg <= 0 ||
      period_low_deg <= period_high_deg) {
    std::ostringstream msg;
    msg << "fringe periods high = " << period_high_deg << " deg, low = " << period_low_deg
        << " deg: two-wavelength unwrapping needs 0 < high period < low period";
    throw std::invalid_argument(msg.str());
  }
  ratio_high_ = period_low_deg / (period_low_deg - period_high_deg);
  if (!(ratio_high_ <= kMaxRatio)) {
    std::ostringstream msg;
    msg << "fringe periods high = " << period_high_deg << " deg, low = " << period_low_deg
        << " deg are too close: the equivalent period is " << ratio_high_
        << " high periods, more than the supported " << kMaxRatio;
    throw std::invalid_argument(msg.str());
  }
  const double nearest = std::round(ratio_high_);
  ratio_is_integer_ = std::abs(ratio_high_ - nearest) <= 1e-9 * nearest;
  if (ratio_is_integer_) ratio_high_ = nearest;

  // Largest shift with (R + 3.5)·2^(16+shift) < 2^31: keeps unwrapFixed in int32.
  int shift = 0;
  while (shift < 14 && (ratio_high_ + 3.5) * std::ldexp(1.0, 16 + shift + 1) < 2147483647.0) {
    ++shift;
  }
  params_.shift = shift;
  params_.ratio_q = static_cast<std::int32_t>(std::llround(std::ldexp(ratio_high_, shift)));
  params_.orders_high = static_cast<std::int32_t>(std::ceil(ratio_high_ - 1e-9));
  params_.orders_low = static_cast<std::int32_t>(std::ceil(ratio_high_ - 1 - 1e-9));
  if (params_.orders_low < 1) params_.orders_low = 1;
}

ReferenceOrders TwoWavelengthUnwrapper::unwrap(double phi_high_rad, double phi_low_rad,
                                               double centre_rad) const {
  double equivalent = phi_high_rad - phi_low_rad;
  if (equivalent < 0) equivalent += kTwoPi;
  const double x = ratio_high_ * equivalent - phi_high_rad - centre_rad;
  const double raw = std::floor(x / kTwoPi + 0.5);
  ReferenceOrders out;
  out.residual_rad = x - kTwoPi * raw;
  const int k = static_cast<int>(raw);
  out.high = wrapOrder(k, params_.orders_high);
  out.low = wrapOrder(k - (phi_high_rad < phi_low_rad ? 1 : 0), params_.orders_low);
  return out;
}

std::int32_t TwoWavelengthUnwrapper::fixedResidualBound(double bound_rad) const {
  return static_cast<std::int32_t>(
      std::llround(bound_rad / kTwoPi * std::ldexp(1.0, 16 + params_.shift)));
}

double TwoWavelengthUnwrapper::fixedResidualToRadians(std::int32_t residual) const {
  return residual * kTwoPi / std::ldexp(1.0, 16 + params_.shift);
}

}  // namespace cylscan::algo
