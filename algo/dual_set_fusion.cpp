// SPDX-License-Identifier: Apache-2.0
#include "algo/dual_set_fusion.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cylscan::algo {

DualSetFusion::DualSetFusion(double period_high_deg, double period_low_deg, double noise_gain_high,
                             double noise_gain_low, double equivalent_period_in_high_periods)
    : low_to_high_(period_low_deg / period_high_deg),
      gamma_(noise_gain_high / (noise_gain_low * low_to_high_ * low_to_high_)),
      seam_rad_(2 * std::numbers::pi * equivalent_period_in_high_periods) {
  if (!(low_to_high_ > 0) || !(gamma_ > 0) || !std::isfinite(gamma_)) {
    throw std::invalid_argument("dual-set fusion needs positive periods and noise gains");
  }
  fixed_.low_to_high = static_cast<float>(low_to_high_);
  fixed_.gamma = static_cast<float>(gamma_);
  fixed_.seam = static_cast<float>(equivalent_period_in_high_periods * 65536.0);
  fixed_.low_to_high_q10 = static_cast<std::int32_t>(std::lround(low_to_high_ * 1024.0));
  fixed_.half_seam =
      static_cast<std::int32_t>(std::lround(equivalent_period_in_high_periods * 32768.0));
}

double DualSetFusion::lowFraction(double modulation_high, double modulation_low) const {
  const double weight_low = gamma_ * modulation_low * modulation_low;
  const double weight_sum = weight_low + modulation_high * modulation_high;
  return weight_sum > 0 ? weight_low / weight_sum : 0.0;
}

double DualSetFusion::fuse(double absolute_high_rad, double absolute_low_rad,
                           double modulation_high, double modulation_low) const {
  double difference = low_to_high_ * absolute_low_rad - absolute_high_rad;
  if (difference > 0.5 * seam_rad_) difference -= seam_rad_;
  if (difference < -0.5 * seam_rad_) difference += seam_rad_;
  return absolute_high_rad + lowFraction(modulation_high, modulation_low) * difference;
}

double DualSetFusion::expectedNoiseRatio(double modulation_high, double modulation_low) const {
  const double ratio = gamma_ * modulation_low * modulation_low /
                       (modulation_high * modulation_high);  // w_low / w_high
  return 1.0 / std::sqrt(1.0 + ratio);
}

}  // namespace cylscan::algo
