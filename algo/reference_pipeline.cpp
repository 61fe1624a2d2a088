// SPDX-License-Identifier: Apache-2.0
// The double-precision reference pipeline: double sums, the same least-squares
// weights in double, std::atan2, unwrapping in radians. For tests and comparisons.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <vector>

#include "algo/neighbour_orders.hpp"
#include "algo/numbers.hpp"
#include "algo/order_residual.hpp"
#include "algo/phase_pipeline.hpp"

namespace cylscan::algo {
namespace {

class ReferencePipeline final : public PhasePipeline {
 public:
  explicit ReferencePipeline(const PipelineSetup& setup)
      : setup_(setup), pixels_(setup.pixels()), saturated_(pixels_) {
    for (int i = 0; i < 2; ++i) {
      sum_c_[i].assign(pixels_, 0.0);
      sum_s_[i].assign(pixels_, 0.0);
      sum_a_[i].assign(pixels_, 0.0);
    }
  }

  void beginSet(FringeSet) override {}

  void fold(FringeSet set, int k, const cv::Mat& frame, bool /*completes_set*/) override {
    const int i = fringeSetIndex(set);
    foldReferenceFrame(setup_.weights(set).frame(static_cast<std::size_t>(k)), frame,
                       setup_.options, sum_c_[i].data(), sum_s_[i].data(), sum_a_[i].data(),
                       saturated_.data());
  }

  void finalizeCompact(CompactPhase& /*out*/) const override {
    throw std::logic_error("finalizeCompact(): only the fixed-point path has a compact form");
  }

  void finalize(PhaseMaps& maps) const override {
    preparePhaseMaps(maps, setup_.size);
    const PhaseOptions& o = setup_.options;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    maps.order_residual = residualRule().report;
    const double centre = maps.order_residual.centre_rad;
    const double bound = maps.order_residual.bound_rad;
    std::size_t valid = 0;
    for (std::size_t p = 0; p < pixels_; ++p) {
      const double phi_h = referenceWrappedPhase(sum_s_[0][p], sum_c_[0][p]);
      const double phi_l = referenceWrappedPhase(sum_s_[1][p], sum_c_[1][p]);
      const double b_h = std::hypot(sum_c_[0][p], sum_s_[0][p]);
      const double b_l = std::hypot(sum_c_[1][p], sum_s_[1][p]);
      const ReferenceOrders orders = setup_.unwrapper.unwrap(phi_h, phi_l, centre);
      std::uint8_t bad = 0;
      if (b_h < o.min_modulation || b_l < o.min_modulation) bad |= kLowModulation;
      if (saturated_[p] != 0) bad |= kSaturated;
      if (std::abs(orders.residual_rad) > bound) bad |= kOrderInconsistent;
      const double absolute_high = phi_h + kTwoPi * orders.high;
      const double absolute_low = phi_l + kTwoPi * orders.low;
      maps.wrapped_high.ptr<float>()[p] = wrappedFloat(phi_h);
      maps.wrapped_low.ptr<float>()[p] = wrappedFloat(phi_l);
      maps.modulation_high.ptr<float>()[p] = static_cast<float>(b_h);
      maps.modulation_low.ptr<float>()[p] = static_cast<float>(b_l);
      maps.texture.ptr<float>()[p] = static_cast<float>((sum_a_[0][p] + sum_a_[1][p]) / 2);
      maps.fringe_order.ptr<std::int16_t>()[p] = static_cast<std::int16_t>(orders.high);
      maps.absolute.ptr<float>()[p] = bad != 0 ? nan : static_cast<float>(absolute_high);
      maps.fused.ptr<float>()[p] =
          bad != 0 ? nan
                   : static_cast<float>(setup_.fusion.fuse(absolute_high, absolute_low, b_h, b_l));
      maps.invalid.ptr<std::uint8_t>()[p] = bad;
      valid += bad == 0 ? 1 : 0;
    }
    valid += decideFromNeighbours(maps, centre);
    maps.valid_fraction = static_cast<double>(valid) / static_cast<double>(pixels_);
  }

  void reset() override {
    for (int i = 0; i < 2; ++i) {
      std::fill(sum_c_[i].begin(), sum_c_[i].end(), 0.0);
      std::fill(sum_s_[i].begin(), sum_s_[i].end(), 0.0);
      std::fill(sum_a_[i].begin(), sum_a_[i].end(), 0.0);
    }
    std::fill(saturated_.begin(), saturated_.end(), std::uint8_t{0});
  }

  std::size_t workingStateBytes() const override {
    return pixels_ * (6 * sizeof(double) + sizeof(std::uint8_t));
  }

 private:
  // The fixed path's neighbour rule (algo/neighbour_orders.hpp) in radians.
  std::size_t decideFromNeighbours(PhaseMaps& maps, double centre) const {
    const double seam = kTwoPi * setup_.unwrapper.ordersHigh();
    const double quarter = kTwoPi / 4;
    const float* absolute = maps.absolute.ptr<float>();
    const auto absolute_of = [&](std::size_t j) { return static_cast<double>(absolute[j]); };
    const auto decide = [&](std::size_t i, double mean) {
      const double phi_h = referenceWrappedPhase(sum_s_[0][i], sum_c_[0][i]);
      const double phi_l = referenceWrappedPhase(sum_s_[1][i], sum_c_[1][i]);
      const ReferenceOrders orders = setup_.unwrapper.unwrap(phi_h, phi_l, centre);
      const int step = orders.residual_rad > 0 ? 1 : -1;
      const int orders_high = setup_.unwrapper.ordersHigh();
      const int orders_low = setup_.unwrapper.ordersLow();
      for (const int d : {0, step}) {
        const int high = (orders.high + d + orders_high) % orders_high;
        const double absolute_high = phi_h + kTwoPi * high;
        const double off = std::remainder(absolute_high - mean, seam);
        if (std::abs(off) > quarter) continue;
        const int low = (orders.low + d + orders_low) % orders_low;
        const double absolute_low = phi_l + kTwoPi * low;
        const double b_h = std::hypot(sum_c_[0][i], sum_s_[0][i]);
        const double b_l = std::hypot(sum_c_[1][i], sum_s_[1][i]);
        maps.fringe_order.ptr<std::int16_t>()[i] = static_cast<std::int16_t>(high);
        maps.absolute.ptr<float>()[i] = static_cast<float>(absolute_high);
        maps.fused.ptr<float>()[i] =
            static_cast<float>(setup_.fusion.fuse(absolute_high, absolute_low, b_h, b_l));
        return true;
      }
      return false;
    };
    maps.order_residual.decided_by_neighbours =
        algo::decideOrdersFromNeighbours(setup_.size, maps.invalid.ptr<std::uint8_t>(),
                                         kOrderInconsistent, quarter, absolute_of, decide);
    return maps.order_residual.decided_by_neighbours;
  }

  // The scan's residual rule from the same sample of pixels as the fixed path,
  // its residuals quantised to the fixed path's unit.
  ResidualRule residualRule() const {
    const PhaseOptions& o = setup_.options;
    const int bits = 16 + setup_.unwrapper.fixedParams().shift;
    const double units_per_rad = std::ldexp(1.0, bits) / kTwoPi;
    std::vector<std::int32_t> residuals;
    const std::size_t stride = residualSampleStride(setup_.size);
    for (std::size_t p = 0; p < pixels_; p += stride) {
      if (saturated_[p] != 0 || std::hypot(sum_c_[0][p], sum_s_[0][p]) < o.min_modulation ||
          std::hypot(sum_c_[1][p], sum_s_[1][p]) < o.min_modulation)
        continue;
      const ReferenceOrders orders =
          setup_.unwrapper.unwrap(referenceWrappedPhase(sum_s_[0][p], sum_c_[0][p]),
                                  referenceWrappedPhase(sum_s_[1][p], sum_c_[1][p]));
      residuals.push_back(wrapResidual(std::llround(orders.residual_rad * units_per_rad), bits));
    }
    return algo::residualRule(residuals, setup_);
  }

  const PipelineSetup& setup_;
  std::size_t pixels_;
  std::vector<double> sum_c_[2], sum_s_[2], sum_a_[2];
  std::vector<std::uint8_t> saturated_;
};

}  // namespace

void foldReferenceFrame(const FrameWeights& w, const cv::Mat& frame, const PhaseOptions& resolved,
                        double* sum_c, double* sum_s, double* sum_a, std::uint8_t* saturated) {
  const auto saturation = static_cast<double>(resolved.saturation_level);
  const auto max_pixel = static_cast<double>((1 << resolved.bit_depth) - 1);
  const auto cols = static_cast<std::size_t>(frame.cols);
  for (int r = 0; r < frame.rows; ++r) {
    for (std::size_t x = 0; x < cols; ++x) {
      const double raw =
          frame.depth() == CV_8U ? frame.ptr<std::uint8_t>(r)[x] : frame.ptr<std::uint16_t>(r)[x];
      const std::size_t p = static_cast<std::size_t>(r) * cols + x;
      if (raw >= saturation) saturated[p] = 1;
      const double v = std::min(raw, max_pixel);
      sum_c[p] += w.c * v;
      sum_s[p] += w.s * v;
      sum_a[p] += w.a * v;
    }
  }
}

double referenceWrappedPhase(double s, double c) {
  double phi = std::atan2(s, c);
  if (phi < 0) phi += kTwoPi;
  return phi >= kTwoPi ? 0.0 : phi;
}

float wrappedFloat(double phi) {
  constexpr float kBelowTwoPi = 6.2831850f;  // largest float < 2π
  auto f = static_cast<float>(phi);
  return f > kBelowTwoPi ? 0.0f : f;
}

std::unique_ptr<PhasePipeline> makeReferencePipeline(const PipelineSetup& setup) {
  return std::make_unique<ReferencePipeline>(setup);
}

}  // namespace cylscan::algo
