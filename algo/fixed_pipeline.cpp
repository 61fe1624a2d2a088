// SPDX-License-Identifier: Apache-2.0
// The fixed-point pipeline: the device's path.
//
// Working state per pixel (16 bytes for a two-set scan):
//   uint32 C, S   the live set's sums (reused by the second set); once a set
//                 is complete, C holds its PackedPhase (binary phase and
//                 modulation code), computed by the fold of its last frame
//   uint32 A      the texture sum of both sets; its LSB is the saturation flag
//   uint32 P1     the first set's PackedPhase (its C, kept when it completed)
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <utility>
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
        first_packed_(pixels_) {
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
    // The first set's phase was kept by its last fold; the next fold
    // overwrites the sums.
    mode_ = FoldMode::kStartSet;
  }

  void fold(FringeSet set, int k, const cv::Mat& frame, bool completes_set) override {
    const FixedSetWeights& w = weights_[fringeSetIndex(set)];
    FoldWeights fw = fold_limits_;
    fw.c = w.c[static_cast<std::size_t>(k)];
    fw.s = w.s[static_cast<std::size_t>(k)];
    fw.a = w.a[static_cast<std::size_t>(k)];
    if (!completes_set) {
      foldFixedFrame(isa_, mode_, frame, fw, sum_c_.data(), sum_s_.data(), sum_a_.data());
    } else {
      foldFixedFrameToPhase(isa_, mode_, frame, fw, code_per_sum_[fringeSetIndex(set)],
                            sum_c_.data(), sum_s_.data(), sum_a_.data());
      // The first set's phase is kept; its memory becomes the second set's C.
      if (set == *first_) std::swap(sum_c_, first_packed_);
    }
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
    std::size_t valid =
        combineKernel(isa_, p, pixels_, sum_a_.data(), highPacked(), lowPacked(), out);
    const auto absolute_of = [&](std::size_t j) {
      return std::int64_t{out.fringe_order[j]} * kUnitsPerTurn + phasesAt(j).high;
    };
    const auto decide = [&](std::size_t i, std::int64_t mean) {
      const PixelPhases ph = phasesAt(i);
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
    std::size_t valid =
        combineKernel(isa_, p, pixels_, sum_a_.data(), highPacked(), lowPacked(), compact);
    const auto absolute_of = [&](std::size_t j) { return std::int64_t{compact.absolute[j]}; };
    const auto decide = [&](std::size_t i, std::int64_t mean) {
      const PixelPhases ph = phasesAt(i);
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
    return pixels_ * (sizeof(std::uint32_t) * 3 + sizeof(PackedPhase));
  }

 private:
  // The combine's parameters for this scan: the second set's, and the residual
  // rule measured on a sample of its well-modulated, unsaturated pixels.
  CombineParams scanParams(OrderResidual& report) const {
    CombineParams p = combine_;
    std::vector<std::int32_t> residuals;
    const std::size_t stride = residualSampleStride(setup_.size);
    residuals.reserve(pixels_ / stride + 1);
    for (std::size_t i = 0; i < pixels_; i += stride) {
      const PixelPhases ph = phasesAt(i);
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

  // Both complete sets' PackedPhase maps: the first set's kept, the second's
  // in place of its C.
  const PackedPhase* highPacked() const {
    return *second_ == FringeSet::High ? sum_c_.data() : first_packed_.data();
  }
  const PackedPhase* lowPacked() const {
    return *second_ == FringeSet::High ? first_packed_.data() : sum_c_.data();
  }

  PixelPhases phasesAt(std::size_t i) const {
    const PackedPhase high = highPacked()[i];
    const PackedPhase low = lowPacked()[i];
    return {packedAngle(high), packedAngle(low), packedCode(high), packedCode(low)};
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
  std::vector<PackedPhase> first_packed_;
  std::optional<FringeSet> first_, second_;
  FoldMode mode_ = FoldMode::kStartScan;
};

}  // namespace

namespace {
// Calls fold(pixels, count, offset) once for a continuous frame, else per row.
template <typename Fold>
void foldRows(const cv::Mat& frame, Fold fold) {
  const int rows = frame.isContinuous() ? 1 : frame.rows;
  const auto row_pixels =
      static_cast<std::size_t>(frame.isContinuous() ? frame.total() : frame.cols);
  for (int r = 0; r < rows; ++r) {
    const std::size_t offset = static_cast<std::size_t>(r) * row_pixels;
    if (frame.depth() == CV_8U) {
      fold(frame.ptr<std::uint8_t>(r), row_pixels, offset);
    } else {
      fold(frame.ptr<std::uint16_t>(r), row_pixels, offset);
    }
  }
}
}  // namespace

void foldFixedFrame(KernelIsa isa, FoldMode mode, const cv::Mat& frame, const FoldWeights& w,
                    std::uint32_t* sum_c, std::uint32_t* sum_s, std::uint32_t* sum_a) {
  foldRows(frame, [&](const auto* pixels, std::size_t n, std::size_t offset) {
    foldKernel(isa, mode, pixels, n, w, sum_c + offset, sum_s + offset, sum_a + offset);
  });
}

void foldFixedFrameToPhase(KernelIsa isa, FoldMode mode, const cv::Mat& frame, const FoldWeights& w,
                           float code_per_sum, std::uint32_t* sum_c, const std::uint32_t* sum_s,
                           std::uint32_t* sum_a) {
  foldRows(frame, [&](const auto* pixels, std::size_t n, std::size_t offset) {
    foldPhaseKernel(isa, mode, pixels, n, w, code_per_sum, sum_c + offset, sum_s + offset,
                    sum_a + offset);
  });
}

std::unique_ptr<PhasePipeline> makeFixedPipeline(const PipelineSetup& setup) {
  return std::make_unique<FixedPipeline>(setup);
}

}  // namespace cylscan::algo
