// SPDX-License-Identifier: Apache-2.0
// Internal: the two implementations behind PhaseEngine (fixed point and reference).
// PhaseEngine checks arguments and the order of folds; pipelines only compute.
#pragma once

#include <cstddef>
#include <memory>
#include <opencv2/core.hpp>
#include <span>

#include "algo/dual_set_fusion.hpp"
#include "algo/fixed_kernels.hpp"
#include "algo/phase_engine.hpp"
#include "algo/shift_weights.hpp"
#include "algo/temporal_unwrapping.hpp"

namespace cylscan::algo {

// PhaseOptions with every default resolved; std::invalid_argument for bad ones.
PhaseOptions resolvePhaseOptions(PhaseOptions options);
// PhaseEngine::fold's checks of the frame itself for frame k of `set`:
// std::invalid_argument saying what is wrong.
void checkFoldFrame(FringeSet set, int k, const cv::Mat& frame, cv::Size size, int bit_depth);

// The fixed path's modulation code: 32768 codes per full scale (1/128 count at
// 8 bits, 2 counts at 16).
double modulationCodesPerCount(int max_pixel);
// The modulation code below which the fixed path flags a pixel kLowModulation.
std::uint32_t minModulationCode(const PhaseOptions& resolved);
// One checked frame into the fixed path's sums: foldKernel over its rows.
void foldFixedFrame(KernelIsa isa, FoldMode mode, const cv::Mat& frame, const FoldWeights& w,
                    std::uint32_t* sum_c, std::uint32_t* sum_s, std::uint32_t* sum_a);
// The frame that completes a set: foldPhaseKernel over its rows (the set's
// PackedPhase written over sum_c).
void foldFixedFrameToPhase(KernelIsa isa, FoldMode mode, const cv::Mat& frame, const FoldWeights& w,
                           float code_per_sum, std::uint32_t* sum_c, const std::uint32_t* sum_s,
                           std::uint32_t* sum_a);

// One checked frame into the reference path's sums (C, S, A += w·I, counts
// clamped to full scale); saturated[p] is set where the pixel reaches the
// saturation level.
void foldReferenceFrame(const FrameWeights& w, const cv::Mat& frame, const PhaseOptions& resolved,
                        double* sum_c, double* sum_s, double* sum_a, std::uint8_t* saturated);
// The reference path's φ = atan2(s, c) in [0, 2π).
double referenceWrappedPhase(double s, double c);
// φ in [0, 2π) as a float that is still below 2π.
float wrappedFloat(double phi);

// Everything the pipelines need, with every option resolved.
struct PipelineSetup {
  // Validates everything; throws as PhaseEngine's constructor documents.
  PipelineSetup(cv::Size size, const PhaseOptions& options, const FringeSetGeometry& high,
                const FringeSetGeometry& low);

  cv::Size size;
  PhaseOptions options;
  ShiftWeights high, low;
  TwoWavelengthUnwrapper unwrapper;
  DualSetFusion fusion;

  int maxPixel() const { return (1 << options.bit_depth) - 1; }
  std::size_t pixels() const { return static_cast<std::size_t>(size.area()); }
  const ShiftWeights& weights(FringeSet set) const { return set == FringeSet::High ? high : low; }
};

class PhasePipeline {
 public:
  virtual ~PhasePipeline() = default;
  // Called once per set, before its first frame; the second call ends the first set.
  virtual void beginSet(FringeSet set) = 0;
  // frame: the checked CV_8UC1 / CV_16UC1 of the setup's size; completes_set:
  // it is the set's last frame to be folded.
  virtual void fold(FringeSet set, int k, const cv::Mat& frame, bool completes_set) = 0;
  // Both sets complete.
  virtual void finalize(PhaseMaps& maps) const = 0;
  // Both sets complete; throws std::logic_error where the path has no compact form.
  virtual void finalizeCompact(CompactPhase& out) const = 0;
  virtual void reset() = 0;
  virtual std::size_t workingStateBytes() const = 0;
};

// The residual rule of one scan: the centre the orders are taken about and the
// bound on the residual, in FixedOrders::residual units, with its report.
struct ResidualRule {
  std::int32_t centre = 0;
  std::int32_t bound = 0;
  OrderResidual report;
};
// From the residuals (about 0, in FixedOrders::residual units) of the sampled
// well-modulated pixels; `residuals` is reordered. The bound is the options'
// when they give one.
ResidualRule residualRule(std::span<std::int32_t> residuals, const PipelineSetup& setup);
// Every stride-th pixel is sampled for the rule: about 8192 of them, a stride
// that is odd and does not divide the width, so the samples cover the image.
std::size_t residualSampleStride(cv::Size size);

std::unique_ptr<PhasePipeline> makeFixedPipeline(const PipelineSetup& setup);
std::unique_ptr<PhasePipeline> makeReferencePipeline(const PipelineSetup& setup);

// Allocates (or reuses, when size and type fit and the data is continuous) all maps.
void preparePhaseMaps(PhaseMaps& maps, cv::Size size);
void prepareCompactPhase(CompactPhase& out, cv::Size size);

}  // namespace cylscan::algo
