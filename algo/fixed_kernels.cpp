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

// Pixels per block of the combine pass: its temporaries stay in L1.
constexpr std::size_t kBlock = 512;

// ---- fold ------------------------------------------------------------------

template <FoldMode kMode, typename Pixel>
CYLSCAN_INLINE_BODY void foldLoop(const Pixel* __restrict frame, std::size_t n, FoldWeights w,
                                  std::uint32_t* __restrict sum_c, std::uint32_t* __restrict sum_s,
                                  std::uint32_t* __restrict sum_a) {
  const auto qc = static_cast<std::uint32_t>(w.c);
  const auto qs = static_cast<std::uint32_t>(w.s);
  const auto qa = static_cast<std::uint32_t>(w.a);
  const std::uint32_t saturation = w.saturation;
  const std::uint32_t max_pixel = w.max_pixel;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t v = frame[i];
    const std::uint32_t flag = v >= saturation ? 1u : 0u;
    if constexpr (sizeof(Pixel) > 1) v = v < max_pixel ? v : max_pixel;
    const std::uint32_t c = kMode == FoldMode::kAccumulate ? sum_c[i] : 0u;
    const std::uint32_t s = kMode == FoldMode::kAccumulate ? sum_s[i] : 0u;
    const std::uint32_t a = kMode == FoldMode::kStartScan ? 0u : sum_a[i];
    sum_c[i] = c + qc * v;
    sum_s[i] = s + qs * v;
    sum_a[i] = (a + qa * v) | flag;
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

CYLSCAN_INLINE_BODY void phaseBody(const std::uint32_t* __restrict sum_c,
                                   const std::uint32_t* __restrict sum_s, std::size_t n,
                                   float code_per_sum, BinaryAngle* __restrict phase,
                                   std::uint16_t* __restrict modulation) {
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<std::int32_t>(sum_c[i]);
    const auto s = static_cast<std::int32_t>(sum_s[i]);
    const BinaryPolar polar = binaryPolar(s, c);
    float code = polar.magnitude * code_per_sum + 0.5f;
    code = code < 65535.0f ? code : 65535.0f;
    phase[i] = polar.angle;
    modulation[i] = static_cast<std::uint16_t>(static_cast<std::int32_t>(code));
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

CYLSCAN_INLINE_BODY std::size_t combineBlock(
    const CombineParams& p, std::size_t n, const BinaryAngle* __restrict phase_high,
    const BinaryAngle* __restrict phase_low, const std::uint16_t* __restrict mod_high,
    const std::uint16_t* __restrict mod_low, const std::uint32_t* __restrict sum_a,
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
    const BinaryAngle h = phase_high[i];
    const BinaryAngle l = phase_low[i];
    const std::uint32_t mh = mod_high[i];
    const std::uint32_t ml = mod_low[i];
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

// The compact outputs of one block: the same arithmetic as combineBlock up to the
// conversion to radians, which is left to the reader of the compact maps.
CYLSCAN_INLINE_BODY std::size_t combineCompactBlock(
    const CombineParams& p, std::size_t n, const BinaryAngle* __restrict phase_high,
    const BinaryAngle* __restrict phase_low, const std::uint16_t* __restrict mod_high,
    const std::uint16_t* __restrict mod_low, const std::uint32_t* __restrict sum_a,
    std::int32_t* __restrict absolute, float* __restrict fused, std::uint8_t* __restrict invalid,
    std::uint16_t* __restrict texture) {
  const CombineParams params = p;  // a local copy: nothing the loop stores can alias it
  const float texture_code_per_sum = p.texture_code_per_sum;
  constexpr std::uint32_t kInvalidAbsolute = 0x80000000u;  // INT32_MIN
  std::size_t valid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const BinaryAngle h = phase_high[i];
    const BinaryAngle l = phase_low[i];
    const std::uint32_t mh = mod_high[i];
    const std::uint32_t ml = mod_low[i];
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

CYLSCAN_INLINE_BODY std::size_t combineBlockTo(const CombineParams& p, std::size_t m,
                                               std::size_t start, const BinaryAngle* ph,
                                               const BinaryAngle* pl, const std::uint16_t* mh,
                                               const std::uint16_t* ml, const std::uint32_t* sum_a,
                                               const CombineOutputs& out) {
  return combineBlock(p, m, ph, pl, mh, ml, sum_a + start, out.wrapped_high + start,
                      out.wrapped_low + start, out.modulation_high + start,
                      out.modulation_low + start, out.texture + start, out.absolute + start,
                      out.fused + start, out.fringe_order + start, out.invalid + start);
}

CYLSCAN_INLINE_BODY std::size_t combineBlockTo(const CombineParams& p, std::size_t m,
                                               std::size_t start, const BinaryAngle* ph,
                                               const BinaryAngle* pl, const std::uint16_t* mh,
                                               const std::uint16_t* ml, const std::uint32_t* sum_a,
                                               const CompactOutputs& out) {
  return combineCompactBlock(p, m, ph, pl, mh, ml, sum_a + start, out.absolute + start,
                             out.fused + start, out.invalid + start, out.texture + start);
}

template <typename Outputs>
CYLSCAN_INLINE_BODY std::size_t combineBody(const CombineParams& p, std::size_t n,
                                            const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                                            const std::uint32_t* sum_a,
                                            const BinaryAngle* first_phase,
                                            const std::uint16_t* first_modulation,
                                            const Outputs& out) {
  const float code_per_sum = p.second_code_per_sum;
  alignas(64) BinaryAngle second_phase[kBlock];
  alignas(64) std::uint16_t second_modulation[kBlock];
  std::size_t valid = 0;
  for (std::size_t start = 0; start < n; start += kBlock) {
    const std::size_t m = n - start < kBlock ? n - start : kBlock;
    phaseBody(sum_c + start, sum_s + start, m, code_per_sum, second_phase, second_modulation);
    const BinaryAngle* stored_phase = first_phase + start;
    const std::uint16_t* stored_mod = first_modulation + start;
    const BinaryAngle* ph = p.second_is_high ? second_phase : stored_phase;
    const BinaryAngle* pl = p.second_is_high ? stored_phase : second_phase;
    const std::uint16_t* mh = p.second_is_high ? second_modulation : stored_mod;
    const std::uint16_t* ml = p.second_is_high ? stored_mod : second_modulation;
    valid += combineBlockTo(p, m, start, ph, pl, mh, ml, sum_a, out);
  }
  return valid;
}

// ---- the ISA variants --------------------------------------------------------

void fold8Baseline(FoldMode mode, const std::uint8_t* f, std::size_t n, const FoldWeights& w,
                   std::uint32_t* c, std::uint32_t* s, std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
void fold16Baseline(FoldMode mode, const std::uint16_t* f, std::size_t n, const FoldWeights& w,
                    std::uint32_t* c, std::uint32_t* s, std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
void phaseBaseline(const std::uint32_t* c, const std::uint32_t* s, std::size_t n, float k,
                   BinaryAngle* phase, std::uint16_t* mod) {
  phaseBody(c, s, n, k, phase, mod);
}
std::size_t combineBaseline(const CombineParams& p, std::size_t n, const std::uint32_t* c,
                            const std::uint32_t* s, const std::uint32_t* a,
                            const BinaryAngle* phase, const std::uint16_t* mod,
                            const CombineOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}
std::size_t combineBaseline(const CombineParams& p, std::size_t n, const std::uint32_t* c,
                            const std::uint32_t* s, const std::uint32_t* a,
                            const BinaryAngle* phase, const std::uint16_t* mod,
                            const CompactOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}

#if CYLSCAN_AVX2_VARIANT
CYLSCAN_TARGET_AVX2 void fold8Avx2(FoldMode mode, const std::uint8_t* f, std::size_t n,
                                   const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                   std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
CYLSCAN_TARGET_AVX2 void fold16Avx2(FoldMode mode, const std::uint16_t* f, std::size_t n,
                                    const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                    std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
CYLSCAN_TARGET_AVX2 void phaseAvx2(const std::uint32_t* c, const std::uint32_t* s, std::size_t n,
                                   float k, BinaryAngle* phase, std::uint16_t* mod) {
  phaseBody(c, s, n, k, phase, mod);
}
CYLSCAN_TARGET_AVX2 std::size_t combineAvx2(const CombineParams& p, std::size_t n,
                                            const std::uint32_t* c, const std::uint32_t* s,
                                            const std::uint32_t* a, const BinaryAngle* phase,
                                            const std::uint16_t* mod, const CombineOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}
CYLSCAN_TARGET_AVX2 std::size_t combineAvx2(const CombineParams& p, std::size_t n,
                                            const std::uint32_t* c, const std::uint32_t* s,
                                            const std::uint32_t* a, const BinaryAngle* phase,
                                            const std::uint16_t* mod, const CompactOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}
CYLSCAN_TARGET_AVX512 void fold8Avx512(FoldMode mode, const std::uint8_t* f, std::size_t n,
                                       const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                       std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
CYLSCAN_TARGET_AVX512 void fold16Avx512(FoldMode mode, const std::uint16_t* f, std::size_t n,
                                        const FoldWeights& w, std::uint32_t* c, std::uint32_t* s,
                                        std::uint32_t* a) {
  foldBody(mode, f, n, w, c, s, a);
}
CYLSCAN_TARGET_AVX512 void phaseAvx512(const std::uint32_t* c, const std::uint32_t* s,
                                       std::size_t n, float k, BinaryAngle* phase,
                                       std::uint16_t* mod) {
  phaseBody(c, s, n, k, phase, mod);
}
CYLSCAN_TARGET_AVX512 std::size_t combineAvx512(const CombineParams& p, std::size_t n,
                                                const std::uint32_t* c, const std::uint32_t* s,
                                                const std::uint32_t* a, const BinaryAngle* phase,
                                                const std::uint16_t* mod,
                                                const CombineOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}
CYLSCAN_TARGET_AVX512 std::size_t combineAvx512(const CombineParams& p, std::size_t n,
                                                const std::uint32_t* c, const std::uint32_t* s,
                                                const std::uint32_t* a, const BinaryAngle* phase,
                                                const std::uint16_t* mod,
                                                const CompactOutputs& out) {
  return combineBody(p, n, c, s, a, phase, mod, out);
}

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
                            const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                            const std::uint32_t* sum_a, const BinaryAngle* first_phase,
                            const std::uint16_t* first_modulation, const Outputs& out) {
#if CYLSCAN_AVX2_VARIANT
  if (useAvx512(isa)) {
    return combineAvx512(p, n, sum_c, sum_s, sum_a, first_phase, first_modulation, out);
  }
  if (useAvx2(isa)) {
    return combineAvx2(p, n, sum_c, sum_s, sum_a, first_phase, first_modulation, out);
  }
#endif
  (void)isa;
  return combineBaseline(p, n, sum_c, sum_s, sum_a, first_phase, first_modulation, out);
}
}  // namespace

std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                          const std::uint32_t* sum_a, const BinaryAngle* first_phase,
                          const std::uint16_t* first_modulation, const CombineOutputs& out) {
  return dispatchCombine(isa, p, n, sum_c, sum_s, sum_a, first_phase, first_modulation, out);
}

std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                          const std::uint32_t* sum_a, const BinaryAngle* first_phase,
                          const std::uint16_t* first_modulation, const CompactOutputs& out) {
  return dispatchCombine(isa, p, n, sum_c, sum_s, sum_a, first_phase, first_modulation, out);
}

}  // namespace cylscan::algo
