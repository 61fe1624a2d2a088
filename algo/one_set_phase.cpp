// SPDX-License-Identifier: Apache-2.0
#include "algo/one_set_phase.hpp"

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "algo/binary_angle.hpp"
#include "algo/fixed_weights.hpp"
#include "algo/phase_pipeline.hpp"

namespace cylscan::algo {

struct OneSetPhase::Impl {
  Impl(cv::Size size_, FringeSet set_, const FringeSetGeometry& geometry,
       const PhaseOptions& options_)
      : size(size_),
        set(set_),
        options(resolvePhaseOptions(options_)),
        weights(geometry, toString(set_)),
        pixels(static_cast<std::size_t>(size_.area())) {
    if (size.width <= 0 || size.height <= 0) {
      throw std::invalid_argument("OneSetPhase: image size " + std::to_string(size.width) + "x" +
                                  std::to_string(size.height) + " is empty");
    }
    folded.assign(weights.frameCount(), false);
    const int max_pixel = (1 << options.bit_depth) - 1;
    if (options.fixed_point) {
      // The texture scale of this set alone: it is the only one the sum runs over.
      const ShiftWeights* sets[] = {&weights};
      fixed = FixedSetWeights::quantize(weights, max_pixel,
                                        FixedSetWeights::sharedTextureScale(sets, max_pixel));
      code_per_sum = static_cast<float>(modulationCodesPerCount(max_pixel) / fixed.cs_scale);
      fold_limits.saturation = static_cast<std::uint32_t>(options.saturation_level);
      fold_limits.max_pixel = static_cast<std::uint32_t>(max_pixel);
      isa = resolveKernelIsa(options.kernel_isa);
      fixed_c.resize(pixels);
      fixed_s.resize(pixels);
      fixed_a.resize(pixels);
    } else {
      ref_c.assign(pixels, 0.0);
      ref_s.assign(pixels, 0.0);
      ref_a.assign(pixels, 0.0);
      saturated.assign(pixels, 0);
    }
  }

  void finalizeFixed(OneSetMaps& maps) const {
    std::vector<BinaryAngle> phase(pixels);
    std::vector<std::uint16_t> code(pixels);
    phaseKernel(isa, fixed_c.data(), fixed_s.data(), pixels, code_per_sum, phase.data(),
                code.data());
    // The engine's conversions (fixed_kernels.cpp, combine), with this set's own scales.
    const auto radians = static_cast<float>(kRadiansPerBinaryAngle);
    const auto counts_per_code =
        static_cast<float>(1.0 / modulationCodesPerCount((1 << options.bit_depth) - 1));
    const auto counts_per_texture = static_cast<float>(1.0 / static_cast<double>(fixed.a_scale));
    const std::uint32_t min_code = minModulationCode(options);
    for (std::size_t p = 0; p < pixels; ++p) {
      const std::uint32_t a = fixed_a[p];
      const auto bad = static_cast<std::uint8_t>((code[p] < min_code ? kLowModulation : kValid) |
                                                 ((a & 1u) != 0 ? kSaturated : kValid));
      maps.wrapped.ptr<float>()[p] = static_cast<float>(phase[p]) * radians;
      maps.modulation.ptr<float>()[p] = static_cast<float>(code[p]) * counts_per_code;
      maps.texture.ptr<float>()[p] =
          static_cast<float>(static_cast<std::int32_t>(a & ~1u)) * counts_per_texture;
      maps.invalid.ptr<std::uint8_t>()[p] = bad;
    }
  }

  void finalizeReference(OneSetMaps& maps) const {
    for (std::size_t p = 0; p < pixels; ++p) {
      const double b = std::hypot(ref_c[p], ref_s[p]);
      const auto bad =
          static_cast<std::uint8_t>((b < options.min_modulation ? kLowModulation : kValid) |
                                    (saturated[p] != 0 ? kSaturated : kValid));
      maps.wrapped.ptr<float>()[p] = wrappedFloat(referenceWrappedPhase(ref_s[p], ref_c[p]));
      maps.modulation.ptr<float>()[p] = static_cast<float>(b);
      maps.texture.ptr<float>()[p] = static_cast<float>(ref_a[p]);
      maps.invalid.ptr<std::uint8_t>()[p] = bad;
    }
  }

  cv::Size size;
  FringeSet set;
  PhaseOptions options;
  ShiftWeights weights;
  std::size_t pixels;
  std::vector<bool> folded;
  int count = 0;
  // Fixed-point path.
  FixedSetWeights fixed;
  float code_per_sum = 0;
  FoldWeights fold_limits;
  KernelIsa isa = KernelIsa::kAuto;
  std::vector<std::uint32_t> fixed_c, fixed_s, fixed_a;
  // Reference path.
  std::vector<double> ref_c, ref_s, ref_a;
  std::vector<std::uint8_t> saturated;
};

OneSetPhase::OneSetPhase(cv::Size size, FringeSet set, const FringeSetGeometry& geometry,
                         const PhaseOptions& options)
    : impl_(std::make_unique<Impl>(size, set, geometry, options)) {}

OneSetPhase::~OneSetPhase() = default;
OneSetPhase::OneSetPhase(OneSetPhase&&) noexcept = default;
OneSetPhase& OneSetPhase::operator=(OneSetPhase&&) noexcept = default;

void OneSetPhase::fold(int k, const cv::Mat& frame) {
  Impl& im = *impl_;
  const int n = static_cast<int>(im.folded.size());
  const std::string set_name(toString(im.set));
  if (k < 0 || k >= n) {
    throw std::out_of_range("fold(" + set_name + ", k=" + std::to_string(k) + "): the " + set_name +
                            " set has " + std::to_string(n) + " frames (k = 0.." +
                            std::to_string(n - 1) + ")");
  }
  checkFoldFrame(im.set, k, frame, im.size, im.options.bit_depth);
  if (im.folded[static_cast<std::size_t>(k)]) {
    throw std::logic_error("fold(" + set_name + ", k=" + std::to_string(k) + "): frame " +
                           std::to_string(k) + " of the " + set_name + " set was already folded");
  }
  if (im.options.fixed_point) {
    FoldWeights w = im.fold_limits;
    w.c = im.fixed.c[static_cast<std::size_t>(k)];
    w.s = im.fixed.s[static_cast<std::size_t>(k)];
    w.a = im.fixed.a[static_cast<std::size_t>(k)];
    // The first fold of the scan overwrites all sums: no clearing pass.
    const FoldMode mode = im.count == 0 ? FoldMode::kStartScan : FoldMode::kAccumulate;
    foldFixedFrame(im.isa, mode, frame, w, im.fixed_c.data(), im.fixed_s.data(), im.fixed_a.data());
  } else {
    foldReferenceFrame(im.weights.frame(static_cast<std::size_t>(k)), frame, im.options,
                       im.ref_c.data(), im.ref_s.data(), im.ref_a.data(), im.saturated.data());
  }
  im.folded[static_cast<std::size_t>(k)] = true;
  ++im.count;
}

OneSetMaps OneSetPhase::finalize() const {
  const Impl& im = *impl_;
  if (im.count != static_cast<int>(im.folded.size())) {
    throw std::logic_error("finalize(): frames are missing: " + std::string(toString(im.set)) +
                           " " + std::to_string(im.count) + " of " +
                           std::to_string(im.folded.size()) + " folded");
  }
  OneSetMaps maps;
  maps.wrapped.create(im.size, CV_32FC1);
  maps.modulation.create(im.size, CV_32FC1);
  maps.texture.create(im.size, CV_32FC1);
  maps.invalid.create(im.size, CV_8UC1);
  if (im.options.fixed_point) {
    im.finalizeFixed(maps);
  } else {
    im.finalizeReference(maps);
  }
  maps.valid_fraction =
      static_cast<double>(cv::countNonZero(maps.invalid == 0)) / static_cast<double>(im.pixels);
  return maps;
}

FringeSet OneSetPhase::set() const {
  return impl_->set;
}
int OneSetPhase::frameCount() const {
  return static_cast<int>(impl_->folded.size());
}
const PhaseOptions& OneSetPhase::options() const {
  return impl_->options;
}

}  // namespace cylscan::algo
