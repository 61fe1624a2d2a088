// SPDX-License-Identifier: Apache-2.0
#include "algo/sphere_search.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

namespace cylscan::algo {
namespace {

// The sphere through four points: |X|² + D·x + E·y + F·z + G = 0.
std::optional<Sphere> sphereThrough(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  // Relative to a, for conditioning: |Y|² + 2·Y·(a − C) + … ; solve for the centre offset.
  Eigen::Matrix3d m;
  Eigen::Vector3d rhs;
  const Eigen::Vector3d p[3] = {b - a, c - a, d - a};
  for (int i = 0; i < 3; ++i) {
    m.row(i) = 2.0 * p[i].transpose();
    rhs(i) = p[i].squaredNorm();
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(m);
  if (lu.rank() < 3) return std::nullopt;
  // |p_i − o|² = |o|² for the centre offset o from a.
  const Eigen::Vector3d o = lu.solve(rhs);
  if (!o.allFinite()) return std::nullopt;
  return Sphere{a + o, o.norm()};
}

class Search {
 public:
  Search(std::span<const Eigen::Vector3d> points, const SphereSearchOptions& options)
      : points_(points), options_(options), rng_(options.seed) {}

  std::vector<FoundSphere> run() {
    std::vector<std::size_t> remaining(points_.size());
    for (std::size_t i = 0; i < remaining.size(); ++i)
      remaining[i] = i;
    std::vector<FoundSphere> found;
    while (found.size() < options_.max_spheres && remaining.size() >= options_.min_inliers) {
      std::optional<FoundSphere> sphere = best(remaining);
      if (!sphere) break;
      // Remove everything near the sphere (its inliers and its noisy rim).
      const Sphere& s = sphere->fit.sphere;
      const double reach = s.radius + 4 * options_.inlier_threshold_mm;
      std::erase_if(remaining,
                    [&](std::size_t i) { return (points_[i] - s.centre).norm() < reach; });
      found.push_back(std::move(*sphere));
    }
    std::sort(found.begin(), found.end(), [](const FoundSphere& a, const FoundSphere& b) {
      return a.inliers.size() > b.inliers.size();
    });
    return found;
  }

 private:
  bool radiusAccepted(double r, double tolerance) const {
    if (!std::isfinite(r)) return false;
    if (options_.radius_mm > 0) return std::abs(r - options_.radius_mm) <= tolerance;
    return r >= options_.min_radius_mm && r <= options_.max_radius_mm;
  }

  double reachOfSamples() const {
    return options_.radius_mm > 0 ? 2 * options_.radius_mm : 2 * options_.max_radius_mm;
  }

  std::vector<std::size_t> inliersOf(const Sphere& s, const std::vector<std::size_t>& among) const {
    std::vector<std::size_t> in;
    for (std::size_t i : among) {
      if (std::abs(s.signedDistance(points_[i])) <= options_.inlier_threshold_mm) in.push_back(i);
    }
    return in;
  }

  std::optional<FoundSphere> best(const std::vector<std::size_t>& remaining) {
    std::vector<std::size_t> scored = remaining;
    if (scored.size() > options_.max_scored_points) {
      std::shuffle(scored.begin(), scored.end(), rng_);
      scored.resize(options_.max_scored_points);
    }
    std::uniform_int_distribution<std::size_t> pick(0, remaining.size() - 1);
    const double reach = reachOfSamples();
    std::optional<Sphere> winner;
    std::size_t winner_score = 0;
    for (int it = 0; it < options_.iterations; ++it) {
      const Eigen::Vector3d& a = points_[remaining[pick(rng_)]];
      std::array<Eigen::Vector3d, 3> others;
      int have = 0;
      for (int attempt = 0; attempt < 64 && have < 3; ++attempt) {
        const Eigen::Vector3d& q = points_[remaining[pick(rng_)]];
        const double distance = (q - a).norm();
        if (distance < reach && distance > 0.1 * reach / 2) others[have++] = q;
      }
      if (have < 3) continue;
      const std::optional<Sphere> s = sphereThrough(a, others[0], others[1], others[2]);
      if (!s || !radiusAccepted(s->radius, 3 * options_.radius_tolerance_mm)) continue;
      std::size_t score = 0;
      for (std::size_t i : scored)
        score += std::abs(s->signedDistance(points_[i])) <= options_.inlier_threshold_mm;
      if (score > winner_score) {
        winner_score = score;
        winner = s;
      }
    }
    if (!winner) return std::nullopt;
    FoundSphere found;
    found.inliers = inliersOf(*winner, remaining);
    for (int round = 0; round < 4; ++round) {
      if (found.inliers.size() < std::max<std::size_t>(options_.min_inliers, 4))
        return std::nullopt;
      Points3d in;
      for (std::size_t i : found.inliers)
        in.push_back(points_[i]);
      try {
        found.fit = fitSphere(in);
      } catch (const std::invalid_argument&) {
        return std::nullopt;
      }
      std::vector<std::size_t> next = inliersOf(found.fit.sphere, remaining);
      const bool same = next == found.inliers;
      found.inliers = std::move(next);
      if (same) break;
    }
    if (found.inliers.size() < options_.min_inliers ||
        !radiusAccepted(found.fit.sphere.radius, options_.radius_tolerance_mm)) {
      return std::nullopt;
    }
    return found;
  }

  std::span<const Eigen::Vector3d> points_;
  SphereSearchOptions options_;
  std::mt19937_64 rng_;
};

}  // namespace

std::vector<FoundSphere> findSpheres(std::span<const Eigen::Vector3d> points,
                                     const SphereSearchOptions& options) {
  if (options.inlier_threshold_mm <= 0 || options.iterations <= 0) {
    throw std::invalid_argument("sphere search: the inlier threshold and iterations must be > 0");
  }
  return Search(points, options).run();
}

}  // namespace cylscan::algo
