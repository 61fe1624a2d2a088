// SPDX-License-Identifier: Apache-2.0
// The per-pixel loops of the fixed-point path. Written once as portable C++ the
// compiler vectorises, built for the baseline ISA and for the wider ones that
// algo/kernel_isa.hpp lists; all give the same bits. Sums are kept as uint32
// (wrapping arithmetic, no UB); the weights bound them so that, read as int32,
// they are the exact signed sums.
#pragma once

#include <cstddef>
#include <cstdint>

#include "algo/binary_angle.hpp"
#include "algo/dual_set_fusion.hpp"
#include "algo/kernel_isa.hpp"
#include "algo/temporal_unwrapping.hpp"

namespace cylscan::algo {

// Weights of one frame and the pixel limits for FoldKernel.
struct FoldWeights {
  std::int32_t c = 0, s = 0, a = 0;  // a even
  std::uint32_t saturation = 0;      // pixels >= this set the flag
  std::uint32_t max_pixel = 0;       // pixels above are clamped (and flagged: saturation <= max)
};

// How a fold treats the sums it finds: the first frame of a set overwrites C and S
// (no separate clearing pass), the first frame of a scan overwrites A as well.
enum class FoldMode { kAccumulate, kStartSet, kStartScan };

// C += qc·I, S += qs·I, A = (A + qa·I) | saturated, over n pixels.
void foldKernel(KernelIsa isa, FoldMode mode, const std::uint8_t* frame, std::size_t n,
                const FoldWeights& w, std::uint32_t* sum_c, std::uint32_t* sum_s,
                std::uint32_t* sum_a);
void foldKernel(KernelIsa isa, FoldMode mode, const std::uint16_t* frame, std::size_t n,
                const FoldWeights& w, std::uint32_t* sum_c, std::uint32_t* sum_s,
                std::uint32_t* sum_a);

// Binary phase and modulation code of n pixels: phase = atan2(S, C),
// code = min(65535, round(hypot(C, S) · code_per_sum)), IEEE float ops only.
void phaseKernel(KernelIsa isa, const std::uint32_t* sum_c, const std::uint32_t* sum_s,
                 std::size_t n, float code_per_sum, BinaryAngle* phase, std::uint16_t* modulation);

// A complete set's phase and modulation code of one pixel in one word:
// phase | code << 16.
using PackedPhase = std::uint32_t;
inline BinaryAngle packedAngle(PackedPhase p) {
  return static_cast<BinaryAngle>(p & 0xFFFFu);
}
inline std::uint32_t packedCode(PackedPhase p) {
  return p >> 16;
}
inline PackedPhase packPhase(BinaryAngle angle, std::uint32_t code) {
  return angle | (code << 16);
}

// The fold of the frame that completes a set: foldKernel's sums, then the
// set's phase and code from them as phaseKernel computes them, written over
// sum_c as PackedPhase (sum_s is left as it was). Folding the atan2 into the
// last frame's pass saves a pass over the sums.
void foldPhaseKernel(KernelIsa isa, FoldMode mode, const std::uint8_t* frame, std::size_t n,
                     const FoldWeights& w, float code_per_sum, std::uint32_t* sum_c,
                     const std::uint32_t* sum_s, std::uint32_t* sum_a);
void foldPhaseKernel(KernelIsa isa, FoldMode mode, const std::uint16_t* frame, std::size_t n,
                     const FoldWeights& w, float code_per_sum, std::uint32_t* sum_c,
                     const std::uint32_t* sum_s, std::uint32_t* sum_a);

// Everything finalize needs to turn both sets' phases into the output maps.
struct CombineParams {
  FixedUnwrapParams unwrap;
  FixedFusionParams fusion;
  std::int32_t residual_bound = 0;   // |residual| > bound: order inconsistent
  std::uint32_t min_modulation = 0;  // code < this: low modulation
  float radians_per_unit = 0;        // 2π / 65536
  float counts_per_code = 0;         // modulation code → counts
  float counts_per_texture = 0;      // texture sum → counts (mean of both sets' A)
  float texture_code_per_sum = 0;    // texture sum → compact texture code
};

struct CombineOutputs {
  float* wrapped_high;
  float* wrapped_low;
  float* modulation_high;
  float* modulation_low;
  float* texture;
  float* absolute;
  float* fused;
  std::int16_t* fringe_order;
  std::uint8_t* invalid;
};

struct CompactOutputs {
  std::int32_t* absolute;  // K·65536 + φh, INT32_MIN where invalid
  float* fused;            // high binary-angle units, NaN where invalid
  std::uint8_t* invalid;
  std::uint16_t* texture;  // round(texture sum · texture_code_per_sum), clamped to [0, 65535]
};

// One pass over both complete sets: unwrapping, flags, fusion, all output
// maps. Returns the number of valid pixels.
std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_a, const PackedPhase* high,
                          const PackedPhase* low, const CombineOutputs& out);
// The same pass writing only the compact outputs (11 bytes per pixel).
std::size_t combineKernel(KernelIsa isa, const CombineParams& p, std::size_t n,
                          const std::uint32_t* sum_a, const PackedPhase* high,
                          const PackedPhase* low, const CompactOutputs& out);

}  // namespace cylscan::algo
