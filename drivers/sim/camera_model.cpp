// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/camera_model.hpp"

#include <cmath>
#include <stdexcept>

namespace cylscan::sim {

namespace {

void check(bool ok, const CameraParams& p, const char* name, const char* fault) {
  if (!ok) throw std::invalid_argument("camera '" + p.name + "': " + name + ": " + fault);
}

}  // namespace

void validate(const CameraParams& p) {
  check(!p.name.empty(), p, "name", "must not be empty");
  check(p.width >= 16 && p.width <= 16384, p, "width", "must be in [16, 16384]");
  check(p.height >= 16 && p.height <= 16384, p, "height", "must be in [16, 16384]");
  check(p.fx > 0 && p.fy > 0, p, "fx/fy", "must be > 0");
  check(p.cx >= 0 && p.cx <= p.width && p.cy >= 0 && p.cy <= p.height, p, "cx/cy",
        "must lie inside the image");
  check(std::abs(p.k1) < 2 && std::abs(p.k2) < 10, p, "k1/k2", "are implausibly large");
  check(p.bit_depth == 8 || p.bit_depth == 10 || p.bit_depth == 12 || p.bit_depth == 16, p,
        "bit_depth", "must be 8, 10, 12 or 16");
  check(p.exposure_min_us > 0, p, "exposure_min_us", "must be > 0");
  check(p.exposure_max_us >= p.exposure_min_us, p, "exposure_max_us", "must be >= exposure_min_us");
  check(p.exposure_us >= p.exposure_min_us && p.exposure_us <= p.exposure_max_us, p, "exposure_us",
        "must be in [exposure_min_us, exposure_max_us]");
  check(p.gain_min > 0, p, "gain_min", "must be > 0");
  check(p.gain_max >= p.gain_min, p, "gain_max", "must be >= gain_min");
  check(p.gain >= p.gain_min && p.gain <= p.gain_max, p, "gain", "must be in [gain_min, gain_max]");
  check(p.full_well_e >= 100, p, "full_well_e", "must be >= 100");
  check(p.read_noise_e >= 0, p, "read_noise_e", "must be >= 0");
  check(p.trigger_latency_us >= 0, p, "trigger_latency_us", "must be >= 0");
  check(p.readout_us >= 0, p, "readout_us", "must be >= 0");
  check(p.frame_rate_hz > 0, p, "frame_rate_hz", "must be > 0");
  check(p.response_gamma >= 0.2 && p.response_gamma <= 5, p, "response_gamma",
        "must be in [0.2, 5]");
  check(p.line_time_us >= 0 && p.line_time_us * p.height <= 1e6, p, "line_time_us",
        "must be >= 0 and read the frame within 1 s");
}

std::array<double, 3> lookAtRotationDeg(const Vec3& position, const Vec3& target, double roll_deg) {
  const Vec3 z = (target - position).normalized();
  Vec3 x = Vec3::UnitY().cross(z);
  if (x.norm() < 1e-9) throw std::invalid_argument("look_at: the camera looks along the vertical");
  x.normalize();
  const Vec3 y = z.cross(x);
  Mat3 r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  const Mat3 roll = Eigen::AngleAxisd(roll_deg * kDeg, Vec3::UnitZ()).toRotationMatrix();
  return rotationVectorDeg(r * roll);
}

CameraModel::CameraModel(const CameraParams& params) : params_(params) {
  validate(params_);
  centre_ = toVec(params_.position_mm);
  r_cam_main_ = rotationFromVectorDeg(params_.rotation_deg).transpose();
}

std::optional<Eigen::Vector2d> CameraModel::project(const Vec3& x_main) const {
  const Vec3 c = toCamera(x_main);
  if (c.z() <= 1e-9) return std::nullopt;
  const double x = c.x() / c.z(), y = c.y() / c.z();
  const double r2 = x * x + y * y;
  const double f = 1 + params_.k1 * r2 + params_.k2 * r2 * r2;
  return Eigen::Vector2d(params_.fx * x * f + params_.cx, params_.fy * y * f + params_.cy);
}

Eigen::Vector2d CameraModel::undistort(double u, double v) const {
  const double xd = (u - params_.cx) / params_.fx, yd = (v - params_.cy) / params_.fy;
  // Newton on the radius: rd = r (1 + k1 r² + k2 r⁴).
  const double rd = std::hypot(xd, yd);
  if (rd < 1e-15) return {xd, yd};
  double r = rd;
  for (int i = 0; i < 30; ++i) {
    const double r2 = r * r;
    const double g = r * (1 + params_.k1 * r2 + params_.k2 * r2 * r2) - rd;
    const double dg = 1 + 3 * params_.k1 * r2 + 5 * params_.k2 * r2 * r2;
    const double step = g / dg;
    r -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return {xd * r / rd, yd * r / rd};
}

Vec3 CameraModel::rayDirection(double u, double v) const {
  const Eigen::Vector2d n = undistort(u, v);
  return (r_cam_main_.transpose() * Vec3(n.x(), n.y(), 1.0)).normalized();
}

const std::vector<Vec3>& CameraModel::pixelRays() const {
  std::call_once(ray_cache_->once, [this] {
    std::vector<Vec3> rays;
    rays.reserve(static_cast<std::size_t>(params_.width) *
                 static_cast<std::size_t>(params_.height));
    for (int v = 0; v < params_.height; ++v) {
      for (int u = 0; u < params_.width; ++u)
        rays.push_back(rayDirection(u, v));
    }
    ray_cache_->rays = std::move(rays);
  });
  return ray_cache_->rays;
}

CameraParams CameraModel::scaledTo(int width, int height) const {
  CameraParams p = params_;
  const double sx = static_cast<double>(width) / params_.width;
  const double sy = static_cast<double>(height) / params_.height;
  p.width = width;
  p.height = height;
  p.fx *= sx;
  p.fy *= sy;
  p.cx = (params_.cx + 0.5) * sx - 0.5;
  p.cy = (params_.cy + 0.5) * sy - 0.5;
  // The same rolling time from the first row to the last.
  p.line_time_us = params_.line_time_us / sy;
  return p;
}

}  // namespace cylscan::sim
