// SPDX-License-Identifier: Apache-2.0
#include "algo/fixed_kernels.hpp"

#include <bit>
#include <cmath>
#include <cstdlib>
#include <limits>

#if defined(__x86_64__) && defined(__GNUC__)
#define CYLSCAN_AVX2_VARIANT 1
#define CYLSCAN_TARGET_AVX2 __attribute__((target("avx2")))
#define CYLSCAN_TARGET_AVX512 \
  __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq,prefer-vector-width=512")))
#else
#define CYLSCAN_AVX2_VARIANT 0
#endif
#if CYLSCAN_NEON_VARIANT
#define CYLSCAN_TARGET_NEON __attribute__((target("fpu=neon")))
#endif
#define CYLSCAN_INLINE_BODY inline __attribute__((always_inline))

namespace cylscan::algo {
namespace {

// Bits of InvalidReason (phase_engine.hpp checks that they match).
constexpr std::uint8_t kLowModulationBit = 1;
constexpr std::uint8_t kSaturatedBit = 2;
constexpr std::uint8_t kOrderInconsistentBit = 4;

// ---- fold ------------------------------------------------------------------

// One pixel's sums after folding its value v: C and S start from zero with
// each set, A with each scan; A's lowest bit flags saturation.
struct FoldedSums {
  std::uint32_t c, s, a;
};

template <FoldMode kMode, typename Pixel>
CYLSCAN_INLINE_BODY FoldedSums foldPixel(const FoldWeights& w, Pixel pixel, std::uint32_t sum_c,
                                         std::uint32_t sum_s, std::uint32_t sum_a) {
  std::uint32_t v = pixel;
  const std::uint32_t flag = v >= w.saturation ? 1u : 0u;
  if constexpr (sizeof(Pixel) > 1) v = v < w.max_pixel ? v : w.max_pixel;
  const std::uint32_t c = kMode == FoldMode::kAccumulate ? sum_c : 0u;
  const std::uint32_t s = kMode == FoldMode::kAccumulate ? sum_s : 0u;
  const std::uint32_t a = kMode == FoldMode::kStartScan ? 0u : sum_a;
  return {c + static_cast<std::uint32_t>(w.c) * v, s + static_cast<std::uint32_t>(w.s) * v,
          (a + static_cast<std::uint32_t>(w.a) * v) | flag};
}

template <FoldMode kMode, typename Pixel>
CYLSCAN_INLINE_BODY void foldLoop(const Pixel* __restrict frame, std::size_t n, FoldWeights w,
                                  std::uint32_t* __restrict sum_c, std::uint32_t* __restrict sum_s,
                                  std::uint32_t* __restrict sum_a) {
  for (std::size_t i = 0; i < n; ++i) {
    const FoldedSums f = foldPixel<kMode>(w, frame[i], sum_c[i], sum_s[i], sum_a[i]);
    sum_c[i] = f.c;
    sum_s[i] = f.s;
    sum_a[i] = f.a;
  }
}

template <typename Pixel>
CYLSCAN_INLINE_BODY void foldBody(FoldMode mode, const Pixel* __restrict frame, std::size_t n,
                                  const FoldWeights& w, std::uint32_t* __restrict sum_c,
                                  std::uint32_t* __restrict sum_s,
                                  std::uint32_t* __restrict sum_a) {
  switch (mode) {
    case FoldMode::kAccumulate:
      return foldLoop<FoldMode::kAccumulate>(frame, n, w, sum_c, sum_s, sum_a);
    case FoldMode::kStartSet:
      return foldLoop<FoldMode::kStartSet>(frame, n, w, sum_c, sum_s, sum_a);
    case FoldMode::kStartScan:
      return foldLoop<FoldMode::kStartScan>(frame, n, w, sum_c, sum_s, sum_a);
  }
}

// ---- phase -----------------------------------------------------------------

// One pixel's phase and modulation code from its sums.
struct PhaseCode {
  BinaryAngle phase;
  std::uint32_t code;
};

CYLSCAN_INLINE_BODY PhaseCode phaseCode(std::uint32_t sum_c, std::uint32_t sum_s,
                                        float code_per_sum) {
  const BinaryPolar polar =
      binaryPolar(static_cast<std::int32_t>(sum_s), static_cast<std::int32_t>(sum_c));
  float code = polar.magnitude * code_per_sum + 0.5f;
  code = code < 65535.0f ? code : 65535.0f;
  return {polar.angle, static_cast<std::uint32_t>(static_cast<std::int32_t>(code))};
}

CYLSCAN_INLINE_BODY void phaseBody(const std::uint32_t* __restrict sum_c,
                                   const std::uint32_t* __restrict sum_s, std::size_t n,
                                   float code_per_sum, BinaryAngle* __restrict phase,
                                   std::uint16_t* __restrict modulation) {
  for (std::size_t i = 0; i < n; ++i) {
    const PhaseCode pc = phaseCode(sum_c[i], sum_s[i], code_per_sum);
    phase[i] = pc.phase;
    modulation[i] = static_cast<std::uint16_t>(pc.code);
  }
}

// ---- the fold that completes a set -------------------------------------------

template <FoldMode kMode, typename Pixel>
CYLSCAN_INLINE_BODY void foldPhaseLoop(const Pixel* __restrict frame, std::size_t n, FoldWeights w,
                                       float code_per_sum, std::uint32_t* __restrict sum_c,
                                       const std::uint32_t* __restrict sum_s,
                                       std::uint32_t* __restrict sum_a) {
  for (std::size_t i = 0; i < n; ++i) {
    const FoldedSums f = foldPixel<kMode>(w, frame[i], sum_c[i], sum_s[i], sum_a[i]);
    const PhaseCode pc = phaseCode(f.c, f.s, code_per_sum);
    sum_c[i] = packPhase(pc.phase, pc.code);
    sum_a[i] = f.a;
  }
}

template <typename Pixel>
CYLSCAN_INLINE_BODY void foldPhaseBody(FoldMode mode, const Pixel* __restrict frame, std::size_t n,
                                       const FoldWeights& w, float code_per_sum,
                                       std::uint32_t* __restrict sum_c,
                                       const std::uint32_t* __restrict sum_s,
                                       std::uint32_t* __restrict sum_a) {
  switch (mode) {
    case FoldMode::kAccumulate:
      return foldPhaseLoop<FoldMode::kAccumulate>(frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
    case FoldMode::kStartSet:
      return foldPhaseLoop<FoldMode::kStartSet>(frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
    case FoldMode::kStartScan:
      return foldPhaseLoop<FoldMode::kStartScan>(frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
  }
}

// ---- combine ---------------------------------------------------------------

// The quiet NaN where mask is all ones, else value: a bit select, no FP compare,
// so the loop vectorises without speculating FP operations.
CYLSCAN_INLINE_BODY float nanWhere(std::uint32_t mask, float value) {
  constexpr std::uint32_t kQuietNan = 0x7FC00000u;
  return std::bit_cast<float>((std::bit_cast<std::uint32_t>(value) & ~mask) | (kQuietNan & mask));
}

// What both combines compute for one pixel: the fringe orders, Φ of the high
// set in binary-angle units, the fused Φ in the same units and the reasons the
// pixel is invalid (0 when valid).
struct CombinedPixel {
  FixedOrders orders;
  std::int32_t absolute_high;
  float fused_units;
  std::uint32_t bad;
};

CYLSCAN_INLINE_BODY CombinedPixel combinePixel(const CombineParams& p, BinaryAngle h, BinaryAngle l,
                                               std::uint32_t mh, std::uint32_t ml,
                                               std::uint32_t a) {
  CombinedPixel px;
  px.orders = unwrapFixed(p.unwrap, h, l);
  const std::int32_t residual = std::abs(px.orders.residual);
  px.absolute_high = px.orders.high * 65536 + h;
  const std::int32_t absolute_low = px.orders.low * 65536 + l;
  px.bad = static_cast<std::uint32_t>(mh < p.min_modulation) * kLowModulationBit |
           static_cast<std::uint32_t>(ml < p.min_modulation) * kLowModulationBit |
           (a & 1u) * kSaturatedBit |
           static_cast<std::uint32_t>(residual > p.residual_bound) * kOrderInconsistentBit;
  px.fused_units = fuseFixed(p.fusion, px.absolute_high, absolute_low, mh, ml);
  return px;
}

// The output maps are restrict-qualified parameters, not a struct's members:
// with the latter, GCC 12 left this loop scalar, so both combines take them so.
CYLSCAN_INLINE_BODY std::size_t combineMaps(
    const CombineParams& p, std::size_t n, const std::uint32_t* __restrict sum_a,
    const PackedPhase* __restrict high, const PackedPhase* __restrict low,
    float* __restrict wrapped_high, float* __restrict wrapped_low,
    float* __restrict modulation_high, float* __restrict modulation_low, float* __restrict texture,
    float* __restrict absolute, float* __restrict fused, std::int16_t* __restrict fringe_order,
    std::uint8_t* __restrict invalid) {
  const CombineParams params = p;  // a local copy: nothing the loop stores can alias it
  const float rad = p.radians_per_unit;
  const float counts_per_code = p.counts_per_code;
  const float counts_per_texture = p.counts_per_texture;
  std::size_t valid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const BinaryAngle h = packedAngle(high[i]);
    const BinaryAngle l = packedAngle(low[i]);
    const std::uint32_t mh = packedCode(high[i]);
    const std::uint32_t ml = packedCode(low[i]);
    const std::uint32_t a = sum_a[i];
    const CombinedPixel px = combinePixel(params, h, l, mh, ml, a);
    const std::uint32_t bad = px.bad;
    wrapped_high[i] = static_cast<float>(h) * rad;
    wrapped_low[i] = static_cast<float>(l) * rad;
    modulation_high[i] = static_cast<float>(mh) * counts_per_code;
    modulation_low[i] = static_cast<float>(ml) * counts_per_code;
    texture[i] = static_cast<float>(static_cast<std::int32_t>(a & ~1u)) * counts_per_texture;
    const std::uint32_t nan_mask = 0u - static_cast<std::uint32_t>(bad != 0);
    absolute[i] = nanWhere(nan_mask, static_cast<float>(px.absolute_high) * rad);
    fused[i] = nanWhere(nan_mask, px.fused_units * rad);
    fringe_order[i] = static_cast<std::int16_t>(px.orders.high);
    invalid[i] = static_cast<std::uint8_t>(bad);
    valid += bad == 0 ? 1 : 0;
  }
  return valid;
}

CYLSCAN_INLINE_BODY std::size_t combineBody(const CombineParams& p, std::size_t n,
                                            const std::uint32_t* sum_a, const PackedPhase* high,
                                            const PackedPhase* low, const CombineOutputs& out) {
  return combineMaps(p, n, sum_a, high, low, out.wrapped_high, out.wrapped_low, out.modulation_high,
                     out.modulation_low, out.texture, out.absolute, out.fused, out.fringe_order,
                     out.invalid);
}

// The compact outputs: the same arithmetic as above up to the conversion to
// radians, which is left to the reader of the compact maps.
CYLSCAN_INLINE_BODY std::size_t combineCompact(
    const CombineParams& p, std::size_t n, const std::uint32_t* __restrict sum_a,
    const PackedPhase* __restrict high, const PackedPhase* __restrict low,
    std::int32_t* __restrict absolute, float* __restrict fused, std::uint8_t* __restrict invalid,
    std::uint16_t* __restrict texture) {
  const CombineParams params = p;  // a local copy: nothing the loop stores can alias it
  const float texture_code_per_sum = p.texture_code_per_sum;
  constexpr std::uint32_t kInvalidAbsolute = 0x80000000u;  // INT32_MIN
  std::size_t valid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const BinaryAngle h = packedAngle(high[i]);
    const BinaryAngle l = packedAngle(low[i]);
    const std::uint32_t mh = packedCode(high[i]);
    const std::uint32_t ml = packedCode(low[i]);
    const std::uint32_t a = sum_a[i];
    const CombinedPixel px = combinePixel(params, h, l, mh, ml, a);
    const std::uint32_t bad = px.bad;
    float code = static_cast<float>(static_cast<std::int32_t>(a & ~1u)) * texture_code_per_sum;
    code = code + 0.5f;
    code = code < 65535.0f ? code : 65535.0f;
    code = code > 0.0f ? code : 0.0f;
    const std::uint32_t mask = 0u - static_cast<std::uint32_t>(bad != 0);
    absolute[i] = static_cast<std::int32_t>((static_cast<std::uint32_t>(px.absolute_high) & ~mask) |
                                            (kInvalidAbsolute & mask));
    fused[i] = nanWhere(mask, px.fused_units);
    invalid[i] = static_cast<std::uint8_t>(bad);
    texture[i] = static_cast<std::uint16_t>(static_cast<std::int32_t>(code));
    valid += bad == 0 ? 1 : 0;
  }
  return valid;
}

CYLSCAN_INLINE_BODY std::size_t combineBody(const CombineParams& p, std::size_t n,
                                            const std::uint32_t* sum_a, const PackedPhase* high,
                                            const PackedPhase* low, const CompactOutputs& out) {
  return combineCompact(p, n, sum_a, high, low, out.absolute, out.fused, out.invalid, out.texture);
}

// ---- the ISA variants --------------------------------------------------------

// Every kernel of one ISA: the same bodies, compiled with the target's
// attribute and named with its suffix. TARGET is an attribute, which
// parentheses would break.
// NOLINTBEGIN(bugprone-macro-parentheses)
#define CYLSCAN_KERNELS_FOR(SUFFIX, TARGET)                                                \
  TARGET void fold8##SUFFIX(FoldMode mode, const std::uint8_t* f, std::size_t n,           \
                            const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,      \
                            std::uint32_t* a) {                                            \
    foldBody(mode, f, n, w, c, s, a);                                                      \
  }                                                                                        \
  TARGET void fold16##SUFFIX(FoldMode mode, const std::uint16_t* f, std::size_t n,         \
                             const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,     \
                             std::uint32_t* a) {                                           \
    foldBody(mode, f, n, w, c, s, a);                                                      \
  }                                                                                        \
  TARGET void foldPhase8##SUFFIX(FoldMode mode, const std::uint8_t* f, std::size_t n,      \
                                 const FoldWeights& w, float k, std::uint32_t* c,          \
                                 const std::uint32_t* s, std::uint32_t* a) {               \
    foldPhaseBody(mode, f, n, w, k, c, s, a);                                              \
  }                                                                                        \
  TARGET void foldPhase16##SUFFIX(FoldMode mode, const std::uint16_t* f, std::size_t n,    \
                                  const FoldWeights& w, float k, std::uint32_t* c,         \
                                  const std::uint32_t* s, std::uint32_t* a) {              \
    foldPhaseBody(mode, f, n, w, k, c, s, a);                                              \
  }                                                                                        \
  TARGET void phase##SUFFIX(const std::uint32_t* c, const std::uint32_t* s, std::size_t n, \
                            float k, BinaryAngle* phase, std::uint16_t* mod) {             \
    phaseBody(c, s, n, k, phase, mod);                                                     \
  }                                                                                        \
  TARGET std::size_t combine##SUFFIX(const CombineParams& p, std::size_t n,                \
                                     const std::uint32_t* a, const PackedPhase* high,      \
                                     const PackedPhase* low, const CombineOutputs& out) {  \
    return combineBody(p, n, a, high, low, out);                                           \
  }                                                                                        \
  TARGET std::size_t combine##SUFFIX(const CombineParams& p, std::size_t n,                \
                                     const std::uint32_t* a, const PackedPhase* high,      \
                                     const PackedPhase* low, const CompactOutputs& out) {  \
    return combineBody(p, n, a, high, low, out);                                           \
  }
// NOLINTEND(bugprone-macro-parentheses)

// Out of line, as the other ISAs' are, so that each kernel keeps its own
// symbol: tests/algo/vectorised.py reads their instructions by name.
CYLSCAN_KERNELS_FOR(Baseline, __attribute__((noinline)))

#if CYLSCAN_AVX2_VARIANT
CYLSCAN_KERNELS_FOR(Avx2, CYLSCAN_TARGET_AVX2)
CYLSCAN_KERNELS_FOR(Avx512, CYLSCAN_TARGET_AVX512)

bool useAvx512(KernelIsa isa) {
  return resolveKernelIsa(isa) == KernelIsa::kAvx512;
}

bool useAvx2(KernelIsa isa) {
  return resolveKernelIsa(isa) == KernelIsa::kAvx2;
}
#endif

#if CYLSCAN_NEON_VARIANT
// GCC vectorises float arithmetic with ARMv7's NEON only under
// -funsafe-math-optimizations (NEON flushes denormals to zero), so only the
// integer fold gains from it; the phase and combine kernels, mostly float, stay
// the baseline's, and the bits stay IEEE-754's.
CYLSCAN_TARGET_NEON void fold8Neon(FoldMode mode, const std::uint8_t* f, std::size_t n,
                                   const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                   std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
CYLSCAN_TARGET_NEON void fold16Neon(FoldMode mode, const std::uint16_t* f, std::size_t n,
                                    const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                    std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}

bool useNeon(KernelIsa isa) {
  return resolveKernelIsa(isa) == KernelIsa::kNeon;
}
#endif

#undef CYLSCAN_KERNELS_FOR

}  // namespace

void foldKernel(KernelIsa isa, FoldMode mode, const std::uint8_t* frame, std::size_t n,
                const FoldWeights& w, std::uint32_t* sum_c, std::uint32_t* sum_s,
                std::uint32_t* sum_a) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) return fold8Avx512(mode, frame, n, w, sum_c, sum_s, sum_a);
  if (useAvx2(isa)) return fold8Avx2(mode, frame, n, w, sum_c, sum_s, sum_a);
#endif
#if CYLSCAN_NEON_VARIANT
  if (useNeon(isa)) return fold8Neon(mode, frame, n, w, sum_c, sum_s, sum_a);
#endif
  (void)isa;
  fold8Baseline(mode, frame, n, w, sum_c, sum_s, sum_a);
}

void foldKernel(KernelIsa isa, FoldMode mode, const std::uint16_t* frame, std::size_t n,
                const FoldWeights& w, std::uint32_t* sum_c, std::uint32_t* sum_s,
                std::uint32_t* sum_a) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) return fold16Avx512(mode, frame, n, w, sum_c, sum_s, sum_a);
  if (useAvx2(isa)) return fold16Avx2(mode, frame, n, w, sum_c, sum_s, sum_a);
#endif
#if CYLSCAN_NEON_VARIANT
  if (useNeon(isa)) return fold16Neon(mode, frame, n, w, sum_c, sum_s, sum_a);
#endif
  (void)isa;
  fold16Baseline(mode, frame, n, w, sum_c, sum_s, sum_a);
}

void foldPhaseKernel(KernelIsa isa, FoldMode mode, const std::uint8_t* frame, std::size_t n,
                     const FoldWeights& w, float code_per_sum, std::uint32_t* sum_c,
                     const std::uint32_t* sum_s, std::uint32_t* sum_a) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) return foldPhase8Avx512(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
  if (useAvx2(isa)) return foldPhase8Avx2(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
#endif
  (void)isa;
  foldPhase8Baseline(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
}

void foldPhaseKernel(KernelIsa isa, FoldMode mode, const std::uint16_t* frame, std::size_t n,
                     const FoldWeights& w, float code_per_sum, std::uint32_t* sum_c,
                     const std::uint32_t* sum_s, std::uint32_t* sum_a) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) {
    return foldPhase16Avx512(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
  }
  if (useAvx2(isa)) return foldPhase16Avx2(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
#endif
  (void)isa;
  foldPhase16Baseline(mode, frame, n, w, code_per_sum, sum_c, sum_s, sum_a);
}

void phaseKernel(KernelIsa isa, const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                 std::size_t n, float code_per_sum, BinaryAngle* phase, std::uint16_t* modulation) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) return phaseAvx512(sum_c, sum_s, n, code_per_sum, phase, modulation);
  if (useAvx2(isa)) return phaseAvx2(sum_c, sum_s, n, code_per_sum, phase, modulation);
#endif
  (void)isa;
  phaseBaseline(sum_c, sum_s, n, code_per_sum, phase, modulation);
}

namespace {
template <typename Outputs>
std::size_t dispatchCombine(KernelIsa isa, const CombineParams& p, std::size_t n,
                            const std::uint32_t* sum_a, const PackedPhase* high,
                            const PackedPhase* low, const Outputs& out) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) return combineAvx512(p, n, sum_a, high, low, out);
  if (useAvx2(isa)) return combineAvx2(p, n, sum_a, high, low, out);
#endif
  (void)isa;
  return combineBaseline(p, n, sum_a, high, low, out);
}
}  // namespace

std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_a, const PackedPhase* high,
                          const PackedPhase* low, const CombineOutputs& out) {
  return dispatchCombine(isa, p, n, sum_a, high, low, out);
}

std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_a, const PackedPhase* high,
                          const PackedPhase* low, const CompactOutputs& out) {
  return dispatchCombine(isa, p, n, sum_a, high, low, out);
}

}  // namespace cylscan::algo
