// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/projector.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace cylscan::sim {

namespace {

void check(bool ok, const char* name, const char* fault) {
  if (!ok) throw std::invalid_argument(std::string("projector.") + name + ": " + fault);
}

// Fraction of a kernel centred at x that lies inside [a, b].
double kernelOverlap(BlurKernel kernel, double width, double x, double a, double b) {
  if (width <= 0) return (x >= a && x < b) ? 1.0 : 0.0;
  if (kernel == BlurKernel::Gaussian) {
    const double s = width * std::numbers::sqrt2;
    return 0.5 * (std::erf((b - x) / s) - std::erf((a - x) / s));
  }
  const double lo = std::max(a, x - width / 2), hi = std::min(b, x + width / 2);
  return std::max(0.0, hi - lo) / width;
}

double kernelReach(BlurKernel kernel, double width) {
  return kernel == BlurKernel::Gaussian ? 7.0 * width : width / 2;
}

}  // namespace

void validate(const ProjectorParams& p) {
  check(p.radius_mm > 0, "radius_mm", "must be > 0");
  check(p.theta_high_deg > 0 && p.theta_high_deg < 90, "theta_high_deg", "must be in (0, 90)");
  check(p.theta_low_deg > 0 && p.theta_low_deg < 90, "theta_low_deg", "must be in (0, 90)");
  check(p.theta_low_deg != p.theta_high_deg, "theta_low_deg", "must differ from theta_high_deg");
  check(p.duty > 0 && p.duty < 1, "duty", "must be in (0, 1)");
  check(p.source_warmup_drop >= 0 && p.source_warmup_drop < 0.5, "source_warmup_drop",
        "must be in [0, 0.5)");
  check(p.source_warmup_tau_s > 0, "source_warmup_tau_s", "must be > 0");
  check(p.blur_width_deg >= 0 && p.blur_width_deg < 10, "blur_width_deg", "must be in [0, 10)");
  check(p.eccentricity_mm >= 0 && p.eccentricity_mm < p.radius_mm / 2, "eccentricity_mm",
        "must be in [0, radius_mm / 2)");
  const double s = std::hypot(p.source_offset_mm[0], p.source_offset_mm[2]);
  check(s + p.eccentricity_mm < p.radius_mm / 2, "source_offset_mm",
        "must keep the source well inside the cylinder");
  check(p.elevation_min_deg < p.elevation_max_deg && p.elevation_min_deg > -90 &&
            p.elevation_max_deg < 90,
        "elevation_min_deg", "and elevation_max_deg must satisfy -90 < min < max < 90");
  check(p.source_level >= 0, "source_level", "must be >= 0");
  check(p.reference_distance_mm > 0, "reference_distance_mm", "must be > 0");
}

CylindricalProjector::CylindricalProjector(const ProjectorParams& params) : params_(params) {
  validate(params_);
  rotation_ = rotationFromVectorDeg(params_.rotation_deg);
  origin_ = toVec(params_.axis_origin_mm);
  source_local_ = toVec(params_.source_offset_mm);
  source_main_ = origin_ + rotation_ * source_local_;
  radius2_ = params_.radius_mm * params_.radius_mm;

  // Slot centres: m·θh on [0, 180), 180 + offset + m·θl on [180, 360), each
  // with its machining error.
  const double th = params_.theta_high_deg, tl = params_.theta_low_deg;
  std::mt19937_64 rng(params_.slot_error_seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const auto add_slot = [&](double centre, double period) {
    const double c = centre + params_.slot_pitch_error_deg * unit(rng);
    const double w =
        period * std::clamp(params_.duty + params_.slot_width_error * unit(rng), 0.05, 0.95);
    slots_.push_back({c - w / 2, c + w / 2});
  };
  for (int m = 0; m * th < 180.0 - 1e-9; ++m)
    add_slot(m * th, th);
  for (int m = 0; 180.0 + m * tl < 360.0 - 1e-9; ++m)
    add_slot(180.0 + params_.low_half_offset_deg + m * tl, tl);

  table_.assign(kTableSize + 1, 0.0f);
  const double reach = kernelReach(params_.blur_kernel, params_.blur_width_deg);
  std::vector<double> acc(kTableSize, 0.0);
  for (const auto& slot : slots_) {
    const int first = static_cast<int>(std::floor((slot[0] - reach) * kTablePerDeg));
    const int last = static_cast<int>(std::ceil((slot[1] + reach) * kTablePerDeg));
    for (int i = first; i <= last; ++i) {
      const double x = static_cast<double>(i) / kTablePerDeg;
      const double v =
          kernelOverlap(params_.blur_kernel, params_.blur_width_deg, x, slot[0], slot[1]);
      acc[static_cast<std::size_t>(((i % kTableSize) + kTableSize) % kTableSize)] += v;
    }
  }
  for (int i = 0; i < kTableSize; ++i) {
    table_[static_cast<std::size_t>(i)] =
        static_cast<float>(std::clamp(acc[static_cast<std::size_t>(i)], 0.0, 1.0));
  }
  table_[kTableSize] = table_[0];
}

Vec3 CylindricalProjector::toProjector(const Vec3& x_main) const {
  return rotation_.transpose() * (x_main - origin_);
}

double CylindricalProjector::azimuthDeg(const Vec3& x_main) const {
  const Vec3 p = toProjector(x_main);
  return std::atan2(p.x(), p.z()) / kDeg;
}

double CylindricalProjector::elevationDeg(const Vec3& x_main) const {
  const Vec3 d = toProjector(x_main) - source_local_;
  return std::atan2(-d.y(), std::hypot(d.x(), d.z())) / kDeg;
}

bool CylindricalProjector::inVerticalExtent(const Vec3& x_main) const {
  const double e = elevationDeg(x_main);
  return e >= params_.elevation_min_deg && e <= params_.elevation_max_deg;
}

CylindricalProjector::RayGeometry CylindricalProjector::rayGeometry(const Vec3& x_main) const {
  const Vec3 d = toProjector(x_main) - source_local_;
  const double h = std::hypot(d.x(), d.z());
  RayGeometry g;
  if (h <= 0) return g;
  g.ux = static_cast<float>(d.x() / h);
  g.uz = static_cast<float>(d.z() / h);
  // Centred cylinder: crossing of |S + t u| = r.
  const double sx = source_local_.x(), sz = source_local_.z();
  const double ux = d.x() / h, uz = d.z() / h;
  const double b = sx * ux + sz * uz;
  const double c = sx * sx + sz * sz - params_.radius_mm * params_.radius_mm;
  const double t = -b + std::sqrt(b * b - c);
  g.wx = static_cast<float>(sx + t * ux);
  g.wz = static_cast<float>(sz + t * uz);
  g.gamma0_deg = static_cast<float>(std::atan2(sx + t * ux, sz + t * uz) / kDeg);
  return g;
}

CylindricalProjector::CentreOffset CylindricalProjector::centreOffset(double stage_deg) const {
  const double phase = (params_.eccentricity_phase_deg + stage_deg) * kDeg;
  return {params_.eccentricity_mm * std::sin(phase), params_.eccentricity_mm * std::cos(phase)};
}

double CylindricalProjector::wallAngleDeg(const RayGeometry& ray, double stage_deg) const {
  if (!eccentric()) return wrapDeg360(ray.gamma0_deg - stage_deg);
  return wallAngleDeg(ray, centreOffset(stage_deg), stage_deg);
}

double CylindricalProjector::wallAngleDeg(const Vec3& x_main, double stage_deg) const {
  const Vec3 d = toProjector(x_main) - source_local_;
  const double h = std::hypot(d.x(), d.z());
  const double ux = d.x() / h, uz = d.z() / h;
  const double phase = (params_.eccentricity_phase_deg + stage_deg) * kDeg;
  const double e = params_.eccentricity_mm;
  const double dx = source_local_.x() - e * std::sin(phase);
  const double dz = source_local_.z() - e * std::cos(phase);
  const double b = dx * ux + dz * uz;
  const double c = dx * dx + dz * dz - params_.radius_mm * params_.radius_mm;
  const double t = -b + std::sqrt(b * b - c);
  return wrapDeg360(std::atan2(dx + t * ux, dz + t * uz) / kDeg - stage_deg);
}

double CylindricalProjector::slotSum(double beta_deg) const {
  double sum = 0;
  for (const auto& slot : slots_) {
    for (double shift : {-360.0, 0.0, 360.0}) {
      sum += kernelOverlap(params_.blur_kernel, params_.blur_width_deg, beta_deg + shift, slot[0],
                           slot[1]);
    }
  }
  return sum;
}

double CylindricalProjector::transmissionExact(double beta_deg) const {
  return std::clamp(slotSum(wrapDeg360(beta_deg)), 0.0, 1.0);
}

}  // namespace cylscan::sim
