// SPDX-License-Identifier: Apache-2.0
#include "algo/surface_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "algo/numbers.hpp"

namespace cylscan::algo {
namespace {

// splitmix64: a tiny, fully specified generator, so a seed gives the same
// hypotheses on every platform and standard library.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, n) (n ≥ 1); the modulo bias is below 2^-40 for any n we use.
  std::size_t below(std::size_t n) { return static_cast<std::size_t>(next() % n); }

 private:
  std::uint64_t state_;
};

// A canonical orientation for a normal: largest |component| among z, y, x
// (in that order of preference) positive.
Eigen::Vector3d orientNormal(Eigen::Vector3d n) {
  n.normalize();
  const double key = std::abs(n.z()) > 1e-12 ? n.z() : (std::abs(n.y()) > 1e-12 ? n.y() : n.x());
  return key < 0.0 ? Eigen::Vector3d(-n) : n;
}

double rms(std::span<const double> values) {
  double sum = 0.0;
  for (double v : values)
    sum += v * v;
  return values.empty() ? kNaN : std::sqrt(sum / static_cast<double>(values.size()));
}

// Levenberg–Marquardt on residuals r_i(x) of the (scaled) points. `model`
// gives for one point its residual and the gradient of that residual.
template <int N, class Model>
int levenbergMarquardt(std::span<const Eigen::Vector3d> points, Eigen::Matrix<double, N, 1>& x,
                       const Model& model) {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  auto cost = [&](const Vec& params) {
    double c = 0.0;
    Vec unused;
    for (const auto& p : points) {
      const double r = model(p, params, unused);
      c += r * r;
    }
    return c;
  };
  double lambda = 1e-3;
  double current = cost(x);
  int iteration = 0;
  for (; iteration < 200; ++iteration) {
    Mat h = Mat::Zero();
    Vec g = Vec::Zero();
    Vec j;
    for (const auto& p : points) {
      const double r = model(p, x, j);
      h.noalias() += j * j.transpose();
      g.noalias() += j * r;
    }
    bool improved = false;
    while (lambda < 1e12) {
      Mat damped = h;
      for (int i = 0; i < N; ++i)
        damped(i, i) += lambda * std::max(h(i, i), 1e-12);
      const Vec step = damped.ldlt().solve(-g);
      const Vec candidate = x + step;
      const double next = cost(candidate);
      if (std::isfinite(next) && next <= current) {
        const bool converged =
            step.norm() <= 1e-13 * (1.0 + x.norm()) || current - next <= 1e-15 * current;
        x = candidate;
        current = next;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (converged) return iteration + 1;
        break;
      }
      lambda *= 10.0;
    }
    if (!improved) break;  // no step reduces the cost: at a minimum to rounding
  }
  return iteration;
}

// Points centred on their mean and scaled to unit RMS radius, for conditioning.
struct Normalised {
  Points3d points;
  Eigen::Vector3d mean;
  double scale = 1.0;
};

Normalised normalise(std::span<const Eigen::Vector3d> points) {
  Normalised out;
  out.mean = Eigen::Vector3d::Zero();
  for (const auto& p : points)
    out.mean += p;
  out.mean /= static_cast<double>(points.size());
  double sum = 0.0;
  for (const auto& p : points)
    sum += (p - out.mean).squaredNorm();
  out.scale = std::sqrt(sum / static_cast<double>(points.size()));
  if (!(out.scale > 0.0)) throw std::invalid_argument("sphere fit: all points coincide");
  out.points.reserve(points.size());
  for (const auto& p : points)
    out.points.emplace_back((p - out.mean) / out.scale);
  return out;
}

double sphereDistanceModel(const Eigen::Vector3d& q, const Eigen::Vector4d& params,
                           Eigen::Vector4d& gradient) {
  const Eigen::Vector3d d = q - params.head<3>();
  const double norm = d.norm();
  const Eigen::Vector3d unit = norm > 0.0 ? Eigen::Vector3d(d / norm) : Eigen::Vector3d::Zero();
  gradient << -unit, -1.0;
  return norm - params(3);
}

}  // namespace

Points3d pointsFromXyz(std::span<const float> xyz) {
  if (xyz.size() % 3 != 0) throw std::invalid_argument("xyz list length is not a multiple of 3");
  Points3d out;
  out.reserve(xyz.size() / 3);
  for (std::size_t i = 0; i + 2 < xyz.size(); i += 3) {
    if (std::isfinite(xyz[i]) && std::isfinite(xyz[i + 1]) && std::isfinite(xyz[i + 2]))
      out.emplace_back(xyz[i], xyz[i + 1], xyz[i + 2]);
  }
  return out;
}

Points3d pointsFromXyzMap(const cv::Mat& xyz_map) {
  if (xyz_map.type() != CV_32FC3) throw std::invalid_argument("xyz map must be CV_32FC3");
  Points3d out;
  for (int v = 0; v < xyz_map.rows; ++v) {
    const auto* row = xyz_map.ptr<cv::Vec3f>(v);
    for (int u = 0; u < xyz_map.cols; ++u) {
      const cv::Vec3f& p = row[u];
      if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))
        out.emplace_back(p[0], p[1], p[2]);
    }
  }
  return out;
}

ResidualStats residualStats(std::span<const double> residuals) {
  ResidualStats s;
  s.count = residuals.size();
  if (residuals.empty()) {
    s.rmse = s.mean = s.std = kNaN;
    return s;
  }
  double sum = 0.0;
  for (double r : residuals)
    sum += r;
  s.mean = sum / static_cast<double>(s.count);
  double centred = 0.0;
  for (double r : residuals)
    centred += (r - s.mean) * (r - s.mean);
  s.std = std::sqrt(centred / static_cast<double>(s.count));
  s.rmse = rms(residuals);
  return s;
}

PlaneFit fitPlane(std::span<const Eigen::Vector3d> points) {
  if (points.size() < 3) throw std::invalid_argument("plane fit: fewer than 3 points");
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points)
    centroid += p;
  centroid /= static_cast<double>(points.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector3d d = p - centroid;
    covariance.noalias() += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  const Eigen::Vector3d& lambda = eigen.eigenvalues();  // ascending
  if (!(lambda(1) > 1e-12 * lambda(2)) || !(lambda(2) > 0.0))
    throw std::invalid_argument("plane fit: points are collinear");
  PlaneFit fit;
  fit.plane.point = centroid;
  fit.plane.normal = orientNormal(eigen.eigenvectors().col(0));
  fit.count = points.size();
  fit.rmse = rms(planeResiduals(points, fit.plane));
  return fit;
}

std::vector<double> planeResiduals(std::span<const Eigen::Vector3d> points, const Plane& plane) {
  std::vector<double> out;
  out.reserve(points.size());
  for (const auto& p : points)
    out.push_back(plane.signedDistance(p));
  return out;
}

RobustPlaneFit fitPlaneRobust(std::span<const Eigen::Vector3d> points,
                              const RobustPlaneOptions& options) {
  if (points.size() < 3) throw std::invalid_argument("robust plane fit: fewer than 3 points");
  if (!(options.inlier_threshold_mm > 0.0) || options.max_iterations < 1 ||
      !(options.confidence > 0.0 && options.confidence < 1.0) || options.max_scored_points < 3)
    throw std::invalid_argument("robust plane fit: bad options");

  // Hypotheses are scored on an evenly strided subsample (deterministic).
  const std::size_t stride = std::max<std::size_t>(
      1, (points.size() + options.max_scored_points - 1) / options.max_scored_points);
  std::vector<std::size_t> scored;
  for (std::size_t i = 0; i < points.size(); i += stride)
    scored.push_back(i);

  SplitMix64 rng(options.seed);
  const double threshold = options.inlier_threshold_mm;
  std::size_t best_score = 0;
  Plane best;
  double needed = static_cast<double>(options.max_iterations);
  for (int it = 0; it < options.max_iterations && it < needed; ++it) {
    const std::size_t a = rng.below(points.size());
    const std::size_t b = rng.below(points.size());
    const std::size_t c = rng.below(points.size());
    if (a == b || b == c || a == c) continue;
    const Eigen::Vector3d e1 = points[b] - points[a];
    const Eigen::Vector3d e2 = points[c] - points[a];
    const Eigen::Vector3d n = e1.cross(e2);
    if (!(n.norm() > 1e-9 * e1.norm() * e2.norm())) continue;  // degenerate triple
    const Plane hypothesis{points[a], n.normalized()};
    std::size_t score = 0;
    for (std::size_t i : scored)
      score += std::abs(hypothesis.signedDistance(points[i])) < threshold;
    if (score > best_score) {
      best_score = score;
      best = hypothesis;
      const double w = static_cast<double>(score) / static_cast<double>(scored.size());
      const double all_in = w * w * w;
      if (all_in >= 1.0) {
        needed = 0.0;
      } else {
        needed = std::log(1.0 - options.confidence) / std::log(1.0 - all_in);
      }
    }
  }
  if (best_score < 3) throw std::invalid_argument("robust plane fit: no plane with 3 inliers");

  RobustPlaneFit out;
  out.inliers.assign(points.size(), 0);
  Plane plane = best;
  for (int round = 0; round < 10; ++round) {
    std::vector<std::uint8_t> inliers(points.size(), 0);
    Points3d selected;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (std::abs(plane.signedDistance(points[i])) < threshold) {
        inliers[i] = 1;
        selected.push_back(points[i]);
      }
    }
    if (selected.size() < 3) throw std::invalid_argument("robust plane fit: too few inliers");
    const bool unchanged = inliers == out.inliers;
    out.inliers = std::move(inliers);
    out.inlier_count = selected.size();
    out.fit = fitPlane(selected);
    plane = out.fit.plane;
    if (unchanged) break;
  }
  return out;
}

SphereFit fitSphere(std::span<const Eigen::Vector3d> points) {
  if (points.size() < 4) throw std::invalid_argument("sphere fit: fewer than 4 points");
  const Normalised n = normalise(points);

  // Algebraic: |q|² = 2 c·q + d, d = r² − |c|², linear in (c, d).
  Eigen::MatrixXd a(n.points.size(), 4);
  Eigen::VectorXd b(n.points.size());
  for (std::size_t i = 0; i < n.points.size(); ++i) {
    const auto& q = n.points[i];
    a.row(static_cast<Eigen::Index>(i)) << 2.0 * q.x(), 2.0 * q.y(), 2.0 * q.z(), 1.0;
    b(static_cast<Eigen::Index>(i)) = q.squaredNorm();
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  qr.setThreshold(1e-10);
  if (qr.rank() < 4) throw std::invalid_argument("sphere fit: points are coplanar");
  const Eigen::Vector4d linear = qr.solve(b);
  const double r2 = linear(3) + linear.head<3>().squaredNorm();
  if (!(r2 > 0.0)) throw std::invalid_argument("sphere fit: no real sphere through the points");

  Eigen::Vector4d params;
  params << linear.head<3>(), std::sqrt(r2);
  SphereFit fit;
  fit.iterations = levenbergMarquardt<4>(n.points, params, sphereDistanceModel);
  fit.sphere.centre = n.mean + n.scale * params.head<3>();
  fit.sphere.radius = n.scale * params(3);
  fit.count = points.size();
  fit.rmse = rms(sphereResiduals(points, fit.sphere));
  return fit;
}

FixedRadiusSphereFit fitSphereFixedRadius(std::span<const Eigen::Vector3d> points, double radius) {
  if (!(radius > 0.0)) throw std::invalid_argument("fixed-radius sphere fit: radius must be > 0");
  const SphereFit free = fitSphere(points);
  const Normalised n = normalise(points);
  const double r = radius / n.scale;
  Eigen::Vector3d centre = (free.sphere.centre - n.mean) / n.scale;
  auto model = [r](const Eigen::Vector3d& q, const Eigen::Vector3d& c, Eigen::Vector3d& gradient) {
    const Eigen::Vector3d d = q - c;
    const double norm = d.norm();
    gradient = norm > 0.0 ? Eigen::Vector3d(-d / norm) : Eigen::Vector3d::Zero();
    return norm - r;
  };
  FixedRadiusSphereFit fit;
  fit.iterations = levenbergMarquardt<3>(n.points, centre, model);
  fit.sphere.centre = n.mean + n.scale * centre;
  fit.sphere.radius = radius;
  const std::vector<double> residuals = sphereResiduals(points, fit.sphere);
  fit.residuals = residualStats(residuals);
  return fit;
}

std::vector<double> sphereResiduals(std::span<const Eigen::Vector3d> points, const Sphere& sphere) {
  std::vector<double> out;
  out.reserve(points.size());
  for (const auto& p : points)
    out.push_back(sphere.signedDistance(p));
  return out;
}

RegionalRmse regionalRmse(std::span<const double> residuals, std::span<const double> u,
                          double u_min, double u_max) {
  if (residuals.size() != u.size())
    throw std::invalid_argument("regional RMSE: residuals and u differ in length");
  if (!(u_max > u_min)) throw std::invalid_argument("regional RMSE: empty u-range");
  const double range = u_max - u_min;
  const double mid = 0.5 * (u_min + u_max);
  const double band = 0.15 * range;
  double central = 0.0;
  double outer = 0.0;
  RegionalRmse out;
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double r2 = residuals[i] * residuals[i];
    if (std::abs(u[i] - mid) <= band) {
      central += r2;
      ++out.central_count;
    } else if (u[i] <= u_min + band || u[i] >= u_max - band) {
      outer += r2;
      ++out.outer_count;
    }
  }
  out.central =
      out.central_count ? std::sqrt(central / static_cast<double>(out.central_count)) : kNaN;
  out.outer = out.outer_count ? std::sqrt(outer / static_cast<double>(out.outer_count)) : kNaN;
  return out;
}

}  // namespace cylscan::algo
