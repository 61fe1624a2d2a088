// SPDX-License-Identifier: Apache-2.0
// The cylindrical mechanical projector of the paper: a light source inside a
// rotating cylinder whose wall carries ON/OFF slots, θh on one half and θl on
// the other. See docs/virtual-head.md for the model and its conventions.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "drivers/sim/geometry.hpp"

namespace cylscan::sim {

enum class BlurKernel { Gaussian, Box };

struct ProjectorParams {
  // A point of the rotation axis at the height of the source, main camera frame (mm).
  std::array<double, 3> axis_origin_mm{120.0, 0.0, 0.0};
  // Rotation vector (deg) of the projector frame in the main frame. Projector
  // frame: y = the rotation axis (down), z = azimuth 0, x = y × z (azimuth 90°).
  std::array<double, 3> rotation_deg{0.0, 0.0, 0.0};
  double radius_mm = 30.0;
  double theta_high_deg = 5.0;   // slot period on the half β ∈ [0°, 180°)
  double theta_low_deg = 5.625;  // slot period on the half β ∈ [180°, 360°)
  double duty = 0.5;             // open fraction of a period
  // How the cylinder was made. The low half's slots start this far from 180°
  // (the two halves are cut or assembled separately), and every slot's centre
  // and width carry a machining error: Gaussian, σ in degrees and as a
  // fraction of the period, drawn from `slot_error_seed` (the same cylinder on
  // every run).
  double low_half_offset_deg = 0.0;
  double slot_pitch_error_deg = 0.0;
  double slot_width_error = 0.0;
  std::uint64_t slot_error_seed = 1;
  BlurKernel blur_kernel = BlurKernel::Gaussian;
  double blur_width_deg = 0.6;           // Gaussian σ, or the box's full width (0: sharp slots)
  double eccentricity_mm = 0.02;         // cylinder centre off the rotation axis
  double eccentricity_phase_deg = 30.0;  // its azimuth at stage angle 0
  std::array<double, 3> source_offset_mm{0.1, 0.0, 0.05};  // source off the axis, projector frame
  double elevation_min_deg = -25.0;  // vertical extent of the light, from the source (up +)
  double elevation_max_deg = 25.0;
  // Signal of a white (albedo 1) surface at normal incidence, reference
  // distance, fully open slot, reference exposure, as a fraction of full well.
  double source_level = 1.05;
  double reference_distance_mm = 580.0;
  // The LED warms up after it is switched on and its output falls:
  // level · (1 − drop · (1 − exp(−t_on / tau))), t_on the time since the light
  // came on. So the frames of a set see a slowly falling intensity.
  double source_warmup_drop = 0.0;
  double source_warmup_tau_s = 20.0;

  // The source level `seconds_on` after the light came on, as a factor.
  double warmupFactor(double seconds_on) const {
    return 1.0 - source_warmup_drop * (1.0 - std::exp(-seconds_on / source_warmup_tau_s));
  }

  bool operator==(const ProjectorParams&) const = default;
};

// Throws std::invalid_argument naming the parameter when a value is impossible.
void validate(const ProjectorParams& params);

class CylindricalProjector {
 public:
  explicit CylindricalProjector(const ProjectorParams& params);

  const ProjectorParams& params() const { return params_; }

  // Per-point geometry that does not depend on the stage angle.
  struct RayGeometry {
    float ux = 0, uz = 0;  // horizontal unit direction source → point (projector frame)
    float wx = 0, wz = 0;  // wall crossing point for a centred cylinder (from the axis, mm)
    float gamma0_deg = 0;  // its azimuth
  };

  // The cylinder centre's offset from the axis at a stage angle (projector x, z).
  struct CentreOffset {
    double x = 0, z = 0;
  };
  CentreOffset centreOffset(double stage_deg) const;

  Vec3 sourcePosition() const { return source_main_; }  // main frame
  Vec3 toProjector(const Vec3& x_main) const;           // relative to the axis origin
  double azimuthDeg(const Vec3& x_main) const;          // about the axis, (−180, 180]
  double elevationDeg(const Vec3& x_main) const;        // seen from the source
  bool inVerticalExtent(const Vec3& x_main) const;
  RayGeometry rayGeometry(const Vec3& x_main) const;
  bool eccentric() const { return params_.eccentricity_mm != 0.0; }

  // Cylinder angle β in [0, 360) of the wall point that the ray from the
  // source to x crosses at stage angle ρ (exact ray–cylinder intersection,
  // with eccentricity and source offset).
  double wallAngleDeg(const Vec3& x_main, double stage_deg) const;
  double wallAngleDeg(const RayGeometry& ray, double stage_deg) const;
  // The same with the centre offset of the frame computed once (renderer fast path).
  // Exact crossing of the eccentric cylinder |S − C + t u| = r; its azimuth
  // about C is γ0 plus the (small) angle between the centred crossing W0 and
  // W = S − C + t u, both of length r: Δ = atan2(W0 × W, W0 · W).
  double wallAngleDeg(const RayGeometry& ray, const CentreOffset& c, double stage_deg) const {
    const double dx = source_local_.x() - c.x, dz = source_local_.z() - c.z;
    const double ux = ray.ux, uz = ray.uz;
    const double b = dx * ux + dz * uz;
    const double cc = dx * dx + dz * dz - radius2_;
    const double t = -b + std::sqrt(b * b - cc);
    const double wx = dx + t * ux, wz = dz + t * uz;
    const double cross = ray.wz * wx - ray.wx * wz;
    const double dot = ray.wx * wx + ray.wz * wz;
    const double q = cross / dot;                                        // tan Δ, |q| ≲ 2e/r
    const double delta = q * (1.0 - q * q * (1.0 / 3.0 - q * q * 0.2));  // atan, error < q⁷/7
    return static_cast<double>(ray.gamma0_deg) + delta * (180.0 / std::numbers::pi) - stage_deg;
  }

  // Transmission of the wall at cylinder angle β: slots blurred by the kernel, in [0, 1].
  double transmission(double beta_deg) const {  // table, linear interpolation
    double x = beta_deg * kTablePerDeg;
    x -= kTableSize * std::floor(x * (1.0 / kTableSize));
    const int i = std::min(static_cast<int>(x), kTableSize - 1);
    const auto k = static_cast<std::size_t>(i);
    return table_[k] + (x - i) * (table_[k + 1] - table_[k]);
  }
  double transmissionExact(double beta_deg) const;  // analytic sum over slots

  // The transmission table for hot loops: samples every 1/kTablePerDeg degree
  // over [0, 360], kTableSize + 1 entries (the last equals the first).
  const float* table() const { return table_.data(); }
  static constexpr int kTablePerDeg = 1000;
  static constexpr int kTableSize = 360 * kTablePerDeg;
  Vec3 sourceLocal() const { return source_local_; }

  // The open slots as [begin, end) cylinder angles (begin may be < 0).
  const std::vector<std::array<double, 2>>& slots() const { return slots_; }

 private:
  double slotSum(double beta_deg) const;

  ProjectorParams params_;
  Mat3 rotation_;  // projector → main
  Vec3 origin_;
  Vec3 source_local_;
  Vec3 source_main_;
  double radius2_ = 0;
  std::vector<std::array<double, 2>> slots_;
  std::vector<float> table_;  // transmission every kTableStep degrees
};

}  // namespace cylscan::sim
