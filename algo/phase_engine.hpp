// SPDX-License-Identifier: Apache-2.0
// The phase engine: N-step least-squares phase of two fringe sets, two-wavelength
// temporal unwrapping and dual-set fusion (model: docs/formats.md, capture
// bundle; paper Eqs. 4, 6-8).
//
// Frames are folded one at a time into a small per-pixel state; finalize() turns it
// into phase maps. The default fixed-point path is the one the device runs: integer
// sums, binary angles, an atan2 in fixed-order IEEE float operations and integer
// unwrapping, the same bits on any IEEE-754 CPU, 16 bytes of working state per pixel. The
// double-precision reference path (fixed_point = false) is for tests and comparisons.
#pragma once

#include <climits>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

#include "algo/fringe_set.hpp"
#include "algo/kernel_isa.hpp"
#include "algo/shift_weights.hpp"  // ShiftSolveError

namespace cylscan::algo {

struct PhaseOptions {
  int bit_depth = 8;          // significant bits of the frames: 8..16
  int saturation_level = -1;  // counts; -1 means 2^bit_depth - 1
  // Counts of B; -1 means 2 % of full scale (5.1 counts at 8 bits): below it the
  // phase noise σI·sqrt(2/N)/B of a dark or shadowed pixel is too large to trust.
  double min_modulation = -1;
  // Bound on the order residual |R·φeq − φh − 2πK − centre|; -1 means from the
  // scan's own spread (algo/order_residual.hpp: min(6σ, 2π − 4.5σ) within [π/2, 0.9π]),
  // or π/2 when too few pixels are modulated to measure it. A residual of r
  // means the nearest other order would need an error of 2π − |r|.
  double max_order_error_rad = -1;
  // The centre the orders are numbered about, in radians: a quasi-calibration's
  // (QuasiCalibrationInfo::order_centre_rad). The centre is only known modulo
  // 2π, and a centre taken across ±π from the calibration's would number every
  // order one off and move the seam where K wraps; so the measured centre is
  // taken within ±π of this one. Unset: the measured centre, in [−π, π).
  std::optional<double> order_reference_rad;
  bool fixed_point = true;  // false: the double reference path
  // Which build of the fixed-point kernels runs (same bits either way).
  KernelIsa kernel_isa = KernelIsa::kAuto;
};

// The order residual of a scan (algo/order_residual.hpp), in radians: its
// centre, the phase offset between the sets as R·φeq − φh sees it (−R times
// the low set's offset), its robust spread about the centre, and the bound
// the validity rule used.
struct OrderResidual {
  double centre_rad = 0;
  double spread_rad = 0;
  double bound_rad = 0;
  std::size_t samples = 0;  // well-modulated pixels it was measured on; 0: not measured
  // Pixels beyond the bound whose orders their trusted neighbours decided
  // (algo/neighbour_orders.hpp); they count as valid.
  std::size_t decided_by_neighbours = 0;
};

enum InvalidReason : std::uint8_t {
  kValid = 0,
  kLowModulation = 1,
  kSaturated = 2,
  kOrderInconsistent = 4
};

struct PhaseMaps {
  cv::Mat wrapped_high, wrapped_low;        // CV_32FC1 radians in [0, 2π)
  cv::Mat modulation_high, modulation_low;  // CV_32FC1, B in counts
  cv::Mat texture;                          // CV_32FC1, A in counts (mean of both sets)
  // CV_16SC1, K of the high set; computed at every pixel, to be trusted where invalid == 0.
  cv::Mat fringe_order;
  cv::Mat absolute;  // CV_32FC1, Φ = φ_high + 2πK, NaN where invalid
  cv::Mat fused;     // CV_32FC1, fused Φ (same scale as Φ_high), NaN where invalid
  cv::Mat invalid;   // CV_8UC1, InvalidReason bits, 0 = valid
  double valid_fraction = 0;
  OrderResidual order_residual;
};

// The device's output of a scan: what the firmware keeps, 11 bytes per pixel written
// in one pass (PhaseMaps writes 31). Values are the fixed-point path's own, before any
// conversion to radians, so PhaseMaps' fields follow from them exactly where valid:
//   absolute (PhaseMaps) == float(absolute) · float(2π/65536)   (bit for bit)
//   fringe_order == absolute >> 16,  wrapped_high == float(absolute & 0xFFFF) · float(2π/65536)
//   fused (PhaseMaps) == fused · float(2π/65536)                 (bit for bit)
//   invalid and valid_fraction identical.
struct CompactPhase {
  static constexpr std::int32_t kInvalidAbsolute = INT32_MIN;
  // CV_32SC1, Φ of the high set in binary-angle units (65536 per 2π): K·65536 + φh;
  // kInvalidAbsolute where invalid.
  cv::Mat absolute;
  cv::Mat fused;    // CV_32FC1, fused Φ in the same units (fractional), NaN where invalid
  cv::Mat invalid;  // CV_8UC1, InvalidReason bits, 0 = valid
  // CV_16UC1, A (mean of both sets) as a code: round(A · texture_codes_per_count), clamped
  // to [0, 65535]; 65536 codes per full scale (256 per count at 8 bits, 1 at 16 bits).
  cv::Mat texture;
  double texture_codes_per_count = 0;
  double valid_fraction = 0;
  OrderResidual order_residual;
};

class PhaseEngine {
 public:
  // Throws ShiftSolveError (names the set) for singular shifts, std::invalid_argument for
  // bad options/periods.
  PhaseEngine(cv::Size size, FringeSetGeometry high, FringeSetGeometry low,
              PhaseOptions options = {});
  ~PhaseEngine();
  PhaseEngine(PhaseEngine&&) noexcept;
  PhaseEngine& operator=(PhaseEngine&&) noexcept;
  PhaseEngine(const PhaseEngine&) = delete;
  PhaseEngine& operator=(const PhaseEngine&) = delete;

  // Frames of one set must all be folded before the other set's first frame (either set
  // may come first). k is the frame index into that set's stage_deg. Each frame folded
  // exactly once (std::logic_error otherwise; std::out_of_range for a bad k). CV_8UC1
  // (bit_depth 8) or CV_16UC1 (bit_depth 9..16) of `size`; anything else throws
  // std::invalid_argument saying what is wrong. Counts above 2^bit_depth - 1 are clamped
  // and flagged saturated.
  void fold(FringeSet set, int k, const cv::Mat& frame);

  // PhaseOptions::order_reference_rad for the finalizes that follow: the
  // reference of the calibration this camera's phase is used with.
  void setOrderReference(std::optional<double> reference_rad);
  PhaseMaps finalize();  // throws std::logic_error if frames are missing
  // The same into existing maps, reusing their memory when size and type fit.
  // finalize() does not consume the state: it may be called again.
  void finalize(PhaseMaps& maps);
  // The device's finalize: CompactPhase in one fused pass (the second set's atan2,
  // unwrapping, fusion, flags), reusing the memory of `out` when size and type fit.
  // Does not consume the state. Fixed-point path only: the reference path throws
  // std::logic_error, as do missing frames.
  void finalizeCompact(CompactPhase& out);

  // Forget all folded frames and start a new scan with the same geometry.
  void reset();

  std::size_t workingStateBytes() const;  // per-pixel working state actually held, in bytes,
                                          // times pixels

  cv::Size size() const;
  int frameCount(FringeSet set) const;
  double conditionNumber(FringeSet set) const;  // of the set's normal matrix
  double noiseGain(FringeSet set) const;        // var(φ) = gain·σ²/B²
  const PhaseOptions& options() const;          // with every default resolved

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cylscan::algo
