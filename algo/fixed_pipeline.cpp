// SPDX-License-Identifier: Apache-2.0
// The fixed-point pipeline: the device's path.
//
// Working state per pixel (16 bytes for a two-set scan):
//   uint32 C, S   the live set's sums (reused by the second set)
//   uint32 A      the texture sum of both sets; its LSB is the saturation flag
//   uint16 φ1     the first set's binary phase, once that set is complete
//   uint16 B1     the first set's modulation code
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <vector>

#include "algo/fixed_kernels.hpp"
#include "algo/fixed_weights.hpp"
#include "algo/neighbour_orders.hpp"
#include "algo/phase_pipeline.hpp"

namespace cylscan::algo {
namespace {

// Binary-angle units per turn, and the quarter turn within which neighbours
// agree (algo/neighbour_orders.hpp).
constexpr std::int64_t kUnitsPerTurn = 65536;
constexpr std::int64_t kQuarterTurn = kUnitsPerTurn / 4;

// Both sets' phases and modulation codes of one pixel.
struct PixelPhases {
  BinaryAngle high = 0, low = 0;
  std::uint32_t modulation_high = 0, modulation_low = 0;
};

// An ambiguous pixel's order as its neighbours decide it: of its rounded
// order and the next one towards its residual's sign, the one whose Φ is
// within a quarter turn of the neighbours' mean (seam-wrapped), with the
// matching low order.
struct DecidedOrder {
  std::int32_t absolute_high = 0;
  std::int32_t absolute_low = 0;
};

std::optional<DecidedOrder> decideOrder(const FixedUnwrapParams& u, const PixelPhases& ph,
                                        std::int64_t mean) {
  const FixedOrders o = unwrapFixed(u, ph.high, ph.low);
  const std::int32_t step = o.residual > 0 ? 1 : -1;
  const std::int64_t seam = std::int64_t{u.orders_high} * kUnitsPerTurn;
  for (const std::int32_t d : {0, step}) {
    const std::int32_t high = (o.high + d + u.orders_high) % u.orders_high;
    const std::int64_t absolute = std::int64_t{high} * kUnitsPerTurn + ph.high;
    std::int64_t off = (absolute - mean) % seam;
    off = off >= seam / 2 ? off - seam : (off < -seam / 2 ? off + seam : off);
    if (off > kQuarterTurn || off < -kQuarterTurn) continue;
    const std::int32_t low = (o.low + d + u.orders_low) % u.orders_low;
    return DecidedOrder{static_cast<std::int32_t>(absolute),
                        static_cast<std::int32_t>(std::int64_t{low} * kUnitsPerTurn + ph.low)};
  }
  return std::nullopt;
}

class FixedPipeline final : public PhasePipeline {
 public:
  explicit FixedPipeline(const PipelineSetup& setup)
      : setup_(setup),
        isa_(resolveKernelIsa(setup.options.kernel_isa)),
        pixels_(setup.pixels()),
        sum_c_(pixels_),
        sum_s_(pixels_),
        sum_a_(pixels_),
        first_phase_(pixels_),
        first_modulation_(pixels_) {
    const int max_pixel = setup.maxPixel();
    const ShiftWeights* sets[] = {&setup.high, &setup.low};
    const std::int64_t a_scale = FixedSetWeights::sharedTextureScale(sets, max_pixel);
    const double codes_per_count = modulationCodesPerCount(max_pixel);
    for (int i = 0; i < 2; ++i) {
      weights_[i] = FixedSetWeights::quantize(*sets[i], max_pixel, a_scale);
      code_per_sum_[i] = static_cast<float>(codes_per_count / weights_[i].cs_scale);
    }
    const PhaseOptions& o = setup.options;
    combine_.unwrap = setup.unwrapper.fixedParams();
    combine_.fusion = setup.fusion.fixedParams();
    combine_.min_modulation = minModulationCode(o);
    combine_.radians_per_unit = static_cast<float>(2 * std::numbers::pi / 65536.0);
    combine_.counts_per_code = static_cast<float>(1.0 / codes_per_count);
    combine_.counts_per_texture = static_cast<float>(1.0 / (2.0 * static_cast<double>(a_scale)));
    // Compact texture: 65536 codes per full scale.
    texture_codes_per_count_ = 65536.0 / (max_pixel + 1);
    combine_.texture_code_per_sum =
        static_cast<float>(texture_codes_per_count_ / (2.0 * static_cast<double>(a_scale)));
    fold_limits_.saturation = static_cast<std::uint32_t>(o.saturation_level);
    fold_limits_.max_pixel = static_cast<std::uint32_t>(max_pixel);
  }

  void beginSet(FringeSet set) override {
    if (!first_) {
      first_ = set;
      mode_ = FoldMode::kStartScan;
      return;
    }
    second_ = set;
    // The first set is complete: keep its phase and modulation; the next fold
    // overwrites its sums.
    phaseKernel(isa_, sum_c_.data(), sum_s_.data(), pixels_, code_per_sum_[fringeSetIndex(*first_)],
                first_phase_.data(), first_modulation_.data());
    mode_ = FoldMode::kStartSet;
  }

  void fold(FringeSet set, int k, const cv::Mat& frame) override {
    const FixedSetWeights& w = weights_[fringeSetIndex(set)];
    FoldWeights fw = fold_limits_;
    fw.c = w.c[static_cast<std::size_t>(k)];
    fw.s = w.s[static_cast<std::size_t>(k)];
    fw.a = w.a[static_cast<std::size_t>(k)];
    foldFixedFrame(isa_, mode_, frame, fw, sum_c_.data(), sum_s_.data(), sum_a_.data());
    mode_ = FoldMode::kAccumulate;
  }

  void finalize(PhaseMaps& maps) const override {
    preparePhaseMaps(maps, setup_.size);
    const CombineParams p = scanParams(maps.order_residual);
    const CombineOutputs out{
        maps.wrapped_high.ptr<float>(),    maps.wrapped_low.ptr<float>(),
        maps.modulation_high.ptr<float>(), maps.modulation_low.ptr<float>(),
        maps.texture.ptr<float>(),         maps.absolute.ptr<float>(),
        maps.fused.ptr<float>(),           maps.fringe_order.ptr<std::int16_t>(),
        maps.invalid.ptr<std::uint8_t>()};
    std::size_t valid = combineKernel(isa_, p, pixels_, sum_c_.data(), sum_s_.data(), sum_a_.data(),
                                      first_phase_.data(), first_modulation_.data(), out);
    const auto absolute_of = [&](std::size_t j) {
      return std::int64_t{out.fringe_order[j]} * kUnitsPerTurn + phasesAt(j, p).high;
    };
    const auto decide = [&](std::size_t i, std::int64_t mean) {
      const PixelPhases ph = phasesAt(i, p);
      const std::optional<DecidedOrder> order = decideOrder(p.unwrap, ph, mean);
      if (!order) return false;
      out.fringe_order[i] = static_cast<std::int16_t>(order->absolute_high / kUnitsPerTurn);
      out.absolute[i] = static_cast<float>(order->absolute_high) * p.radians_per_unit;
      out.fused[i] = fuseFixed(p.fusion, order->absolute_high, order->absolute_low,
                               ph.modulation_high, ph.modulation_low) *
                     p.radians_per_unit;
      return true;
    };
    maps.order_residual.decided_by_neighbours = decideOrdersFromNeighbours(
        setup_.size, out.invalid, kOrderInconsistent, kQuarterTurn, absolute_of, decide);
    valid += maps.order_residual.decided_by_neighbours;
    maps.valid_fraction = static_cast<double>(valid) / static_cast<double>(pixels_);
  }

  void finalizeCompact(CompactPhase& out) const override {
    prepareCompactPhase(out, setup_.size);
    const CombineParams p = scanParams(out.order_residual);
    const CompactOutputs compact{out.absolute.ptr<std::int32_t>(), out.fused.ptr<float>(),
                                 out.invalid.ptr<std::uint8_t>(), out.texture.ptr<std::uint16_t>()};
    std::size_t valid = combineKernel(isa_, p, pixels_, sum_c_.data(), sum_s_.data(), sum_a_.data(),
                                      first_phase_.data(), first_modulation_.data(), compact);
    const auto absolute_of = [&](std::size_t j) { return std::int64_t{compact.absolute[j]}; };
    const auto decide = [&](std::size_t i, std::int64_t mean) {
      const PixelPhases ph = phasesAt(i, p);
      const std::optional<DecidedOrder> order = decideOrder(p.unwrap, ph, mean);
      if (!order) return false;
      compact.absolute[i] = order->absolute_high;
      compact.fused[i] = fuseFixed(p.fusion, order->absolute_high, order->absolute_low,
                                   ph.modulation_high, ph.modulation_low);
      return true;
    };
    out.order_residual.decided_by_neighbours = decideOrdersFromNeighbours(
        setup_.size, compact.invalid, kOrderInconsistent, kQuarterTurn, absolute_of, decide);
    valid += out.order_residual.decided_by_neighbours;
    out.texture_codes_per_count = texture_codes_per_count_;
    out.valid_fraction = static_cast<double>(valid) / static_cast<double>(pixels_);
  }

  void reset() override {
    // Nothing to clear: the first fold of the scan overwrites all sums.
    first_.reset();
    second_.reset();
  }

  std::size_t workingStateBytes() const override {
    return pixels_ * (sizeof(std::uint32_t) * 3 + sizeof(BinaryAngle) + sizeof(std::uint16_t));
  }

 private:
  // The combine's parameters for this scan: the second set's, and the residual
  // rule measured on a sample of its well-modulated, unsaturated pixels.
  CombineParams scanParams(OrderResidual& report) const {
    CombineParams p = combine_;
    p.second_is_high = *second_ == FringeSet::High;
    p.second_code_per_sum = code_per_sum_[fringeSetIndex(*second_)];
    std::vector<std::int32_t> residuals;
    const std::size_t stride = residualSampleStride(setup_.size);
    residuals.reserve(pixels_ / stride + 1);
    for (std::size_t i = 0; i < pixels_; i += stride) {
      const PixelPhases ph = phasesAt(i, p);
      if (ph.modulation_high < p.min_modulation || ph.modulation_low < p.min_modulation ||
          (sum_a_[i] & 1u) != 0)
        continue;
      residuals.push_back(unwrapFixed(p.unwrap, ph.high, ph.low).residual);
    }
    const ResidualRule rule = residualRule(residuals, setup_);
    p.unwrap.residual_centre = rule.centre;
    p.residual_bound = rule.bound;
    report = rule.report;
    return p;
  }

  // One pixel's phases: the second set's from the live sums, computed as
  // combineKernel computes them, the first set's as stored.
  PixelPhases phasesAt(std::size_t i, const CombineParams& p) const {
    const BinaryPolar second =
        binaryPolar(static_cast<std::int32_t>(sum_s_[i]), static_cast<std::int32_t>(sum_c_[i]));
    float code = second.magnitude * p.second_code_per_sum + 0.5f;  // as phaseKernel
    code = code < 65535.0f ? code : 65535.0f;
    const auto second_code = static_cast<std::uint32_t>(static_cast<std::int32_t>(code));
    PixelPhases ph;
    ph.high = p.second_is_high ? second.angle : first_phase_[i];
    ph.low = p.second_is_high ? first_phase_[i] : second.angle;
    ph.modulation_high = p.second_is_high ? second_code : first_modulation_[i];
    ph.modulation_low = p.second_is_high ? first_modulation_[i] : second_code;
    return ph;
  }

  const PipelineSetup& setup_;
  KernelIsa isa_;
  std::size_t pixels_;
  FixedSetWeights weights_[2];
  float code_per_sum_[2] = {};
  FoldWeights fold_limits_;
  CombineParams combine_;
  double texture_codes_per_count_ = 0;
  std::vector<std::uint32_t> sum_c_, sum_s_, sum_a_;
  std::vector<BinaryAngle> first_phase_;
  std::vector<std::uint16_t> first_modulation_;
  std::optional<FringeSet> first_, second_;
  FoldMode mode_ = FoldMode::kStartScan;
};

}  // namespace

void foldFixedFrame(KernelIsa isa, FoldMode mode, const cv::Mat& frame, const FoldWeights& w,
                    std::uint32_t* sum_c, std::uint32_t* sum_s, std::uint32_t* sum_a) {
  const int rows = frame.isContinuous() ? 1 : frame.rows;
  const auto row_pixels =
      static_cast<std::size_t>(frame.isContinuous() ? frame.total() : frame.cols);
  for (int r = 0; r < rows; ++r) {
    const std::size_t offset = static_cast<std::size_t>(r) * row_pixels;
    if (frame.depth() == CV_8U) {
      foldKernel(isa, mode, frame.ptr<std::uint8_t>(r), row_pixels, w, sum_c + offset,
                 sum_s + offset, sum_a + offset);
    } else {
      foldKernel(isa, mode, frame.ptr<std::uint16_t>(r), row_pixels, w, sum_c + offset,
                 sum_s + offset, sum_a + offset);
    }
  }
}

std::unique_ptr<PhasePipeline> makeFixedPipeline(const PipelineSetup& setup) {
  return std::make_unique<FixedPipeline>(setup);
}

}  // namespace cylscan::algo
