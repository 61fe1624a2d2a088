// SPDX-License-Identifier: Apache-2.0
// Quasi-calibration (the paper's Eq. 10): for every pixel of the main camera,
// X, Y and Z of the surface point as cubic polynomials of the absolute phase Φ,
// fitted from plane poses whose points are known (ray ∩ fitted plane).
//
// Each pixel's polynomial is in a normalised phase t = (Φ − Φc)·g, where Φc is
// the middle of the phases the pixel saw during calibration and g the inverse
// half-range, so t ∈ [−1, 1] over the calibration poses: the 4×4 normal
// equations are then well conditioned and float32 coefficients lose nothing.
// Evaluation is float32 Horner in one fixed order; the code is compiled with
// -ffp-contract=off, so it gives the same bits on x86 and ARM.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <opencv2/core.hpp>

#include "common/vocabulary.hpp"

namespace cylscan::algo {

// One pixel's model, stored as is in the file: 14 little-endian float32.
struct PixelPolynomial {
  float phase_centre = 0.0f;    // Φc
  float phase_inv_half = 0.0f;  // g: t = (Φ − Φc)·g
  float x[4] = {};              // X(t) = x0 + x1·t + x2·t² + x3·t³ (mm)
  float y[4] = {};
  float z[4] = {};
};
static_assert(sizeof(PixelPolynomial) == 56);

// What the file records besides the polynomials.
struct QuasiCalibrationInfo {
  PhaseSource phase_source = PhaseSource::Fused;
  std::uint32_t pose_count = 0;
  std::uint32_t min_poses = 0;
  float pooled_rmse_mm = std::numeric_limits<float>::quiet_NaN();          // Eq. (12), once known
  float sensitivity_mm_per_rad = std::numeric_limits<float>::quiet_NaN();  // S_eff
  // The order-residual centre the poses were unwrapped about
  // (PhaseOptions::order_reference_rad), and the poses' spread about it; NaN
  // when unknown (a version-1 file).
  float order_centre_rad = std::numeric_limits<float>::quiet_NaN();
  float order_spread_rad = std::numeric_limits<float>::quiet_NaN();
};

// Beyond this |t| (the calibrated phase range is |t| ≤ 1) a pixel is not
// extrapolated: 1.5 allows a quarter of the working range on either side.
inline constexpr float kDefaultExtrapolationLimit = 1.5f;

// Evaluation over arrays owned elsewhere: a QuasiCalibration's, or the bytes
// of a serialised calibration used in place (fromBytes, no copy).
class QuasiCalibrationView {
 public:
  QuasiCalibrationView(cv::Size size, const std::uint8_t* valid, const PixelPolynomial* pixels,
                       QuasiCalibrationInfo info);

  // Validates the bytes exactly like QuasiCalibration::deserialize, then
  // points into them. Needs a little-endian host and 4-byte aligned bytes
  // (invalid_argument otherwise). The bytes must outlive the view.
  static QuasiCalibrationView fromBytes(std::span<const std::byte> bytes);

  cv::Size size() const { return size_; }
  const QuasiCalibrationInfo& info() const { return info_; }
  bool valid(int u, int v) const { return valid_[index(u, v)] != 0; }
  const PixelPolynomial& pixel(int u, int v) const { return pixels_[index(u, v)]; }
  std::size_t validCount() const;

  float extrapolationLimit() const { return limit_; }
  void setExtrapolationLimit(float max_abs_t) { limit_ = max_abs_t; }

  // XYZ (mm, main camera frame) of pixel (u, v) at phase phi; NaN when the
  // pixel is invalid, phi is NaN or beyond the extrapolation limit.
  cv::Vec3f evaluate(int u, int v, float phi) const;
  float evaluateDepth(int u, int v, float phi) const;
  // phase: CV_32F of size(), NaN = invalid → CV_32FC3 xyz / CV_32F depth, NaN where invalid.
  cv::Mat evaluate(const cv::Mat& phase) const;
  cv::Mat evaluateDepth(const cv::Mat& phase) const;
  // ∂Z/∂Φ (mm/rad) in double, NaN where evaluate would give NaN.
  double depthSlope(int u, int v, double phi) const;

 private:
  std::size_t index(int u, int v) const {
    return static_cast<std::size_t>(v) * static_cast<std::size_t>(size_.width) +
           static_cast<std::size_t>(u);
  }
  void checkPhase(const cv::Mat& phase) const;

  cv::Size size_;
  const std::uint8_t* valid_;
  const PixelPolynomial* pixels_;
  QuasiCalibrationInfo info_;
  float limit_ = kDefaultExtrapolationLimit;
};

// The calibration as a value: owns its per-pixel validity and polynomials.
class QuasiCalibration {
 public:
  QuasiCalibration(cv::Size size, std::vector<std::uint8_t> valid,
                   std::vector<PixelPolynomial> pixels, QuasiCalibrationInfo info);

  cv::Size size() const { return size_; }
  const QuasiCalibrationInfo& info() const { return info_; }
  void setResidualSummary(float pooled_rmse_mm, float sensitivity_mm_per_rad);
  // QuasiCalibrationInfo::order_centre_rad and order_spread_rad.
  void setOrderResidual(float centre_rad, float spread_rad);
  void setExtrapolationLimit(float max_abs_t) { limit_ = max_abs_t; }

  QuasiCalibrationView view() const;  // valid while *this lives unchanged
  bool valid(int u, int v) const { return view().valid(u, v); }
  std::size_t validCount() const { return view().validCount(); }
  const PixelPolynomial& pixel(int u, int v) const { return view().pixel(u, v); }
  cv::Vec3f evaluate(int u, int v, float phi) const { return view().evaluate(u, v, phi); }
  float evaluateDepth(int u, int v, float phi) const { return view().evaluateDepth(u, v, phi); }
  cv::Mat evaluate(const cv::Mat& phase) const { return view().evaluate(phase); }
  cv::Mat evaluateDepth(const cv::Mat& phase) const { return view().evaluateDepth(phase); }
  double depthSlope(int u, int v, double phi) const { return view().depthSlope(u, v, phi); }

  // Little-endian fixed layout, see quasi_calibration.cpp: a 64-byte header
  // (magic "CYLQCAL1", version, sizes, model id 3 = cubic, phase source,
  // counts, pooled RMSE, S_eff, CRC-32), the validity plane (1 byte a pixel,
  // padded to 4) and 56-byte PixelPolynomial records.
  std::vector<std::byte> serialize() const;
  // invalid_argument naming the fault: truncated, bad magic, unsupported
  // version/model/layout, absurd image size, checksum mismatch, ...
  static QuasiCalibration deserialize(std::span<const std::byte> bytes);
  // invalid_argument when the calibration was made for another image size.
  void requireImageSize(cv::Size expected) const;

 private:
  cv::Size size_;
  std::vector<std::uint8_t> valid_;
  std::vector<PixelPolynomial> pixels_;
  QuasiCalibrationInfo info_;
  float limit_ = kDefaultExtrapolationLimit;
};

struct QuasiCalibrationOptions {
  int min_poses = 6;  // valid poses a pixel needs; > 4 (a cubic plus a residual)
  PhaseSource phase_source = PhaseSource::Fused;
  double min_phase_range_rad = 1e-3;  // a pixel whose Φ barely changed is invalid
};

// Accumulates calibration poses one at a time (O(pixels) memory whatever the
// pose count) and fits every pixel's polynomials.
//
// Numerics: the normalisation is not known before the last pose, so each
// pixel accumulates, in double, the moments Σs^k (k ≤ 6) and Σs^k·X, Y, Z
// (k ≤ 3) of s = Φ − Φ_first, the offset from its own first valid phase (so
// |s| never exceeds the pixel's phase range: no cancellation from large Φ),
// plus its min and max Φ. fit() then picks Φc = mid-range and g = 1/half-range
// (both rounded to float first, exactly as the evaluation will use them),
// maps the moments to t = (s − s0)·g by the binomial theorem (|s0| ≤ half-range,
// so the error grows by at most 3^6 ulps) and solves the 4×4 normal equations
// in t, which are well conditioned on [−1, 1].
class QuasiCalibrationFitter {
 public:
  explicit QuasiCalibrationFitter(cv::Size size, QuasiCalibrationOptions options = {});

  // phase: CV_32F, NaN invalid; target: CV_32FC3, the pose's known points
  // (main camera frame, mm), NaN invalid. A pixel counts when both are finite.
  void addPose(const cv::Mat& phase, const cv::Mat& target_xyz);
  int poseCount() const { return pose_count_; }
  QuasiCalibration fit() const;

 private:
  struct Accumulator {
    double first_phase = 0.0;
    double min_phase = 0.0;
    double max_phase = 0.0;
    double phase_moments[7] = {};   // Σ s^k
    double xyz_moments[3][4] = {};  // Σ s^k·X, Y, Z
    std::uint32_t count = 0;
  };

  cv::Size size_;
  QuasiCalibrationOptions options_;
  std::vector<Accumulator> pixels_;
  int pose_count_ = 0;
};

struct PoseResidual {
  double depth_rmse_mm = 0.0;     // of Z predicted − Z target
  double distance_rmse_mm = 0.0;  // of the 3D distance predicted ↔ target
  std::size_t pixel_count = 0;
};

struct CalibrationResiduals {
  std::vector<PoseResidual> poses;
  double pooled_depth_rmse_mm = 0.0;     // σ_cal, Eq. (12)
  double pooled_distance_rmse_mm = 0.0;  // the same pooled over 3D distances
  double sensitivity_mm_per_rad = 0.0;   // S_eff = <|∂Z/∂Φ|> over all pixels and poses
  std::size_t pixel_count = 0;           // P
};

// Second pass over the calibration poses: residuals of a fitted calibration.
// Keeps a reference to the calibration.
class QuasiCalibrationResiduals {
 public:
  explicit QuasiCalibrationResiduals(const QuasiCalibration& calibration)
      : calibration_(calibration) {}
  void addPose(const cv::Mat& phase, const cv::Mat& target_xyz);
  CalibrationResiduals result() const;

 private:
  const QuasiCalibration& calibration_;
  std::vector<PoseResidual> poses_;
  double depth_sum_ = 0.0;
  double distance_sum_ = 0.0;
  double slope_sum_ = 0.0;
  std::size_t count_ = 0;
};

}  // namespace cylscan::algo
