// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>

namespace cylscan::sim {

namespace {

int threadCount(int requested) {
  if (requested > 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return static_cast<int>(std::clamp(hw, 1u, 2u));
}

// Runs body(row_begin, row_end) over [0, rows) on `threads` threads.
template <typename Body>
void parallelRows(int rows, int threads, const Body& body) {
  threads = std::min(threads, rows);
  if (threads <= 1) {
    body(0, rows);
    return;
  }
  std::vector<std::jthread> workers;
  for (int t = 1; t < threads; ++t) {
    workers.emplace_back([&, t] { body(rows * t / threads, rows * (t + 1) / threads); });
  }
  body(0, rows / threads);
}

struct Lighting {
  double ambient = 0;
  double direct = 0;
  bool hit = false, lit = false, shadow = false;
  Vec3 point;
};

Lighting light(const Scene& scene, const CylindricalProjector& projector, const Ray& ray) {
  Lighting l;
  const auto hit = scene.firstHit(ray, std::numeric_limits<double>::infinity());
  if (!hit) return l;
  l.hit = true;
  l.point = ray.origin + hit->t * ray.dir;
  l.ambient = scene.ambient * hit->albedo;
  Vec3 n = hit->normal;
  if (n.dot(ray.dir) > 0) n = -n;  // the side the camera sees
  const Vec3 source = projector.sourcePosition();
  const Vec3 to_source = source - l.point;
  const double dist = to_source.norm();
  const double cos_i = n.dot(to_source) / dist;
  if (cos_i <= 0 || !projector.inVerticalExtent(l.point)) return l;
  if (scene.occluded(l.point + 1e-6 * std::max(1.0, l.point.norm()) * n, source)) {
    l.shadow = true;
    return l;
  }
  const auto& p = projector.params();
  const double r = p.reference_distance_mm / dist;
  l.direct = p.source_level * hit->albedo * cos_i * r * r;
  l.lit = true;
  return l;
}

// Direction through a sub-pixel position, interpolated bilinearly between the
// cached pixel-centre rays (the distortion is smooth over a pixel).
Vec3 subpixelRay(const std::vector<Vec3>& rays, int width, int height, double u, double v) {
  const double uc = std::clamp(u, 0.0, width - 1.000001),
               vc = std::clamp(v, 0.0, height - 1.000001);
  const int u0 = static_cast<int>(uc), v0 = static_cast<int>(vc);
  const int u1 = std::min(u0 + 1, width - 1), v1 = std::min(v0 + 1, height - 1);
  const double fu = u - u0, fv = v - v0;  // may extrapolate by half a pixel at the border
  auto at = [&](int x, int y) { return rays[static_cast<std::size_t>(y) * width + x]; };
  const Vec3 top = at(u0, v0) * (1 - fu) + at(u1, v0) * fu;
  const Vec3 bottom = at(u0, v1) * (1 - fu) + at(u1, v1) * fu;
  return (top * (1 - fv) + bottom * fv).normalized();
}

}  // namespace

PixelGeometry tracePixels(const Scene& scene, const CameraModel& camera,
                          const CylindricalProjector& projector, const TraceOptions& options) {
  if (options.supersample < 1 || options.supersample > 8) {
    throw std::invalid_argument("tracePixels: supersample must be in [1, 8]");
  }
  PixelGeometry g;
  g.width = camera.width();
  g.height = camera.height();
  const auto n = static_cast<std::size_t>(g.width) * static_cast<std::size_t>(g.height);
  g.ambient.assign(n, 0.0f);
  g.direct.assign(n, 0.0f);
  g.rays.assign(n, {});
  g.points = cv::Mat(g.height, g.width, CV_64FC3, cv::Scalar::all(std::nan("")));
  g.flags = cv::Mat::zeros(g.height, g.width, CV_8U);
  const Vec3 origin = camera.centre();
  const std::vector<Vec3>& rays = camera.pixelRays();
  const int s = options.supersample;
  parallelRows(g.height, threadCount(options.threads), [&](int begin, int end) {
    for (int v = begin; v < end; ++v) {
      for (int u = 0; u < g.width; ++u) {
        const auto i = static_cast<std::size_t>(v) * g.width + u;
        const Lighting centre = light(scene, projector, {origin, rays[i]});
        double ambient = centre.ambient, direct = centre.direct;
        // A pixel on an object's outline whose centre misses it: the
        // projector ray of a part that hits, since its light is in the pixel.
        std::optional<Vec3> edge_hit;
        if (s > 1) {
          ambient = direct = 0;
          for (int sy = 0; sy < s; ++sy) {
            for (int sx = 0; sx < s; ++sx) {
              const double du = (sx + 0.5) / s - 0.5, dv = (sy + 0.5) / s - 0.5;
              const Lighting l = light(
                  scene, projector, {origin, subpixelRay(rays, g.width, g.height, u + du, v + dv)});
              ambient += l.ambient;
              direct += l.direct;
              if (!edge_hit && l.hit && l.direct > 0) edge_hit = l.point;
            }
          }
          ambient /= s * s;
          direct /= s * s;
        }
        g.ambient[i] = static_cast<float>(ambient);
        g.direct[i] = static_cast<float>(direct);
        std::uint8_t f = 0;
        if (centre.hit) {
          f |= PixelGeometry::kHit;
          g.points.at<cv::Vec3d>(v, u) = {centre.point.x(), centre.point.y(), centre.point.z()};
          g.rays[i] = projector.rayGeometry(centre.point);
        } else if (edge_hit) {
          g.rays[i] = projector.rayGeometry(*edge_hit);
        } else {
          g.direct[i] = 0.0f;  // no ray to light it by
        }
        if (centre.lit) f |= PixelGeometry::kLit;
        if (centre.shadow) f |= PixelGeometry::kShadow;
        g.flags.at<std::uint8_t>(v, u) = f;
      }
    }
  });
  return g;
}

NoiseTable::NoiseTable(std::uint64_t seed) : values_(std::size_t{1} << kBits) {
  std::uint64_t state = mixBits(seed ^ 0x6E6F697365ULL);
  auto uniform = [&] {
    state = mixBits(state);
    return (static_cast<double>(state >> 11) + 0.5) * 0x1.0p-53;  // (0, 1)
  };
  for (std::size_t i = 0; i < values_.size(); i += 2) {
    const double r = std::sqrt(-2.0 * std::log(uniform()));
    const double a = 2.0 * std::numbers::pi * uniform();
    values_[i] = static_cast<float>(r * std::cos(a));
    values_[i + 1] = static_cast<float>(r * std::sin(a));
  }
}

namespace {

// One frame's constants, copied out of the objects so that the per-pixel loop
// works on locals only (stores to the 8-bit output may alias anything else).
struct FrameKernel {
  const float* ambient;
  const float* direct;
  const CylindricalProjector::RayGeometry* rays;
  const float* table;
  int samples;
  std::array<double, Exposure::kMaxSamples> rho;
  std::array<double, Exposure::kMaxSamples> cx, cz;  // cylinder-centre term of each sample
  std::array<bool, Exposure::kMaxSamples> light;
  bool eccentric, any_light;
  double sx, sz, r2;
  double electrons_per_unit, counts_per_electron, max_count;
  double source_gain, gamma;
  float read_var, noise_scale;
  const NoiseTable* noise;
  std::uint64_t key;

  static double lookup(const float* table, double beta_deg) {
    constexpr int n = CylindricalProjector::kTableSize;
    double x = beta_deg * CylindricalProjector::kTablePerDeg;
    x -= n * std::floor(x * (1.0 / n));
    const int i = std::min(static_cast<int>(x), n - 1);
    return table[i] + (x - i) * (table[i + 1] - table[i]);
  }

  double wallAngle(const CylindricalProjector::RayGeometry& ray, int s) const {
    const auto k = static_cast<std::size_t>(s);
    if (!eccentric) return static_cast<double>(ray.gamma0_deg) - rho[k];
    // As CylindricalProjector::wallAngleDeg(ray, centre, ρ).
    const double dx = sx - cx[k], dz = sz - cz[k];
    const double ux = ray.ux, uz = ray.uz;
    const double b = dx * ux + dz * uz;
    const double t = -b + std::sqrt(b * b - (dx * dx + dz * dz - r2));
    const double wx = dx + t * ux, wz = dz + t * uz;
    const double q = (ray.wz * wx - ray.wx * wz) / (ray.wx * wx + ray.wz * wz);
    const double delta = q * (1.0 - q * q * (1.0 / 3.0 - q * q * 0.2));
    return static_cast<double>(ray.gamma0_deg) + delta * (180.0 / std::numbers::pi) - rho[k];
  }

  template <typename Out>
  void row(std::size_t first, int width, Out* out) const {
    const FrameKernel k = *this;  // locals
    const double inv_samples = 1.0 / k.samples;
    for (int u = 0; u < width; ++u) {
      const std::size_t i = first + static_cast<std::size_t>(u);
      double level = k.ambient[i];
      const float d = k.direct[i];
      if (k.any_light && d > 0) {
        double t = 0;
        for (int s = 0; s < k.samples; ++s) {
          if (k.light[static_cast<std::size_t>(s)]) t += lookup(k.table, k.wallAngle(k.rays[i], s));
        }
        level += d * t * inv_samples * k.source_gain;
      }
      double electrons = level * k.electrons_per_unit;
      if (k.noise_scale > 0) {
        const float sigma = k.noise_scale * std::sqrt(static_cast<float>(electrons) + k.read_var);
        electrons += sigma * k.noise->sample(k.key, i);
      }
      double counts = std::clamp(electrons * k.counts_per_electron, 0.0, k.max_count);
      if (k.gamma != 1.0) counts = k.max_count * std::pow(counts / k.max_count, k.gamma);
      // Rounds half up (counts >= 0), never past full scale.
      out[u] = static_cast<Out>(std::min(counts + 0.5, k.max_count));
    }
  }
};

}  // namespace

cv::Mat renderFrame(const PixelGeometry& g, const CylindricalProjector& projector,
                    const Exposure& e, const NoiseTable& noise, int threads) {
  if (e.samples < 1 || e.samples > Exposure::kMaxSamples) {
    throw std::invalid_argument("renderFrame: samples must be in [1, 8]");
  }
  const bool deep = e.bit_depth > 8;
  cv::Mat out(g.height, g.width, deep ? CV_16UC1 : CV_8UC1);
  FrameKernel k{};
  k.ambient = g.ambient.data();
  k.direct = g.direct.data();
  k.rays = g.rays.data();
  k.table = projector.table();
  k.samples = e.samples;
  k.any_light = false;
  for (int s = 0; s < e.samples; ++s) {
    const auto i = static_cast<std::size_t>(s);
    k.rho[i] = e.stage_deg[i];
    k.light[i] = e.light[i];
    k.any_light = k.any_light || e.light[i];
    const auto c = projector.centreOffset(e.stage_deg[i]);
    k.cx[i] = c.x;
    k.cz[i] = c.z;
  }
  k.eccentric = projector.eccentric();
  k.sx = projector.sourceLocal().x();
  k.sz = projector.sourceLocal().z();
  k.r2 = projector.params().radius_mm * projector.params().radius_mm;
  k.max_count = std::ldexp(1.0, e.bit_depth) - 1;
  k.electrons_per_unit = e.full_well_e * e.exposure_us / e.reference_exposure_us;
  k.counts_per_electron = e.gain * k.max_count / e.full_well_e;
  k.read_var = static_cast<float>(e.read_noise_e * e.read_noise_e);
  k.noise_scale = static_cast<float>(e.noise_scale);
  k.noise = &noise;
  k.key = e.noise_key;
  k.source_gain = e.source_gain;
  k.gamma = e.response_gamma;
  parallelRows(g.height, threadCount(threads), [&](int begin, int end) {
    FrameKernel row_kernel = k;
    for (int v = begin; v < end; ++v) {
      if (e.rolling) {
        // This row's exposure: its own stage angles between the first row's and the last's.
        const double f = g.height > 1 ? static_cast<double>(v) / (g.height - 1) : 0.0;
        for (int s = 0; s < e.samples; ++s) {
          const auto i = static_cast<std::size_t>(s);
          const double rho = e.stage_deg[i] + f * (e.stage_deg_last_row[i] - e.stage_deg[i]);
          row_kernel.rho[i] = rho;
          const auto c = projector.centreOffset(rho);
          row_kernel.cx[i] = c.x;
          row_kernel.cz[i] = c.z;
        }
      }
      const std::size_t first = static_cast<std::size_t>(v) * static_cast<std::size_t>(g.width);
      if (deep) {
        row_kernel.row(first, g.width, out.ptr<std::uint16_t>(v));
      } else {
        row_kernel.row(first, g.width, out.ptr<std::uint8_t>(v));
      }
    }
  });
  return out;
}

}  // namespace cylscan::sim
