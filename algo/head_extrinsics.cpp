// SPDX-License-Identifier: Apache-2.0
#include "algo/head_extrinsics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace cylscan::algo {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
// Main's views closer than this in turntable angle do not fix the axis.
constexpr double kMinAxisTurnDeg = 2.0;

Eigen::Matrix3Xd columns(std::span<const Eigen::Vector3d> points) {
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i)
    m.col(static_cast<Eigen::Index>(i)) = points[i];
  return m;
}

// The points span at least a line's worth more than rounding: the second
// singular value of the centred points is not negligible. The singular
// values are the square roots of the 3×3 scatter matrix's eigenvalues; the
// test needs the second to a millionth of the first, far above the
// eigensolver's rounding (1e-16 of the largest eigenvalue, 1e-12 asked).
// The same from an SVD of the 3×N points costs half a minute more to compile
// on every build.
bool collinear(const Eigen::Matrix3Xd& points) {
  const Eigen::Vector3d mean = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - mean;
  const Eigen::Matrix3d scatter = centred * centred.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter, Eigen::EigenvaluesOnly);
  // Ascending; a rounding below zero is no spread at all.
  const Eigen::Vector3d lambda = eigen.eigenvalues().cwiseMax(0.0);
  const double s0 = std::sqrt(lambda(2));
  const double s1 = std::sqrt(lambda(1));
  // 1 µm of spread across the line, or a millionth of the extent.
  return s1 < std::max(1e-3, 1e-6 * s0);
}

double rmsOf(std::span<const double> values) {
  if (values.empty()) return 0.0;
  double sum = 0;
  for (double v : values)
    sum += v * v;
  return std::sqrt(sum / static_cast<double>(values.size()));
}

std::string describe(const TargetView& view) {
  std::string text = "camera '" + view.camera + "' at turn " + std::to_string(view.turn_deg) + "°";
  if (!view.source.empty()) text += " (" + view.source + ")";
  return text;
}

// Step 1: the axis from main's views (rigid motion of every pair).
TurntableAxis fitAxis(const std::vector<const TargetView*>& main_views, double& angle_error_deg) {
  Eigen::Vector3d direction_sum = Eigen::Vector3d::Zero();
  struct Motion {
    RigidPose pose;
    double weight;
  };
  std::vector<Motion> motions;
  angle_error_deg = 0;
  for (std::size_t i = 0; i < main_views.size(); ++i) {
    for (std::size_t j = i + 1; j < main_views.size(); ++j) {
      const TargetView& a = *main_views[i];
      const TargetView& b = *main_views[j];
      const double turn = b.turn_deg - a.turn_deg;
      if (std::abs(turn) < kMinAxisTurnDeg) continue;
      const RigidPose motion = fitRigid(a.centres, b.centres, describe(a) + " and " + describe(b));
      const Eigen::AngleAxisd rotation(motion.R);
      // R = Rot(n, θ) with θ ≥ 0 = Rot(−n, −θ): the direction that turns by +turn.
      const Eigen::Vector3d direction =
          turn >= 0 ? rotation.axis() : Eigen::Vector3d(-rotation.axis());
      const double weight = std::sin(std::min(rotation.angle(), std::numbers::pi / 2));
      direction_sum += weight * direction;
      angle_error_deg =
          std::max(angle_error_deg, std::abs(rotation.angle() / kDegToRad - std::abs(turn)));
      motions.push_back({motion, weight});
    }
  }
  if (motions.empty() || direction_sum.norm() == 0) {
    throw std::invalid_argument(
        "head extrinsics: the turntable axis needs the reference camera at two turntable angles "
        "at least 2° apart; it was seen at fewer");
  }
  TurntableAxis axis;
  axis.direction = direction_sum.normalized();
  // Fixed points: (I − R)·p = T for every motion; the component along the axis
  // is free, fixed by d·p = 0 (the point nearest main's origin).
  Eigen::Matrix3d normal = axis.direction * axis.direction.transpose();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (const Motion& m : motions) {
    const Eigen::Matrix3d a = Eigen::Matrix3d::Identity() - m.pose.R;
    normal += m.weight * a.transpose() * a;
    rhs += m.weight * a.transpose() * m.pose.T;
  }
  const Eigen::Vector3d point = normal.ldlt().solve(rhs);
  axis.point = point - axis.direction.dot(point) * axis.direction;
  return axis;
}

// Step 1b: the axis and the turn-0 target refined together by Gauss–Newton on
// main's views with their known turns: residuals turn(α_i)·X0_k − C_ik. The
// closed form above weights the pairs' rotation axes only roughly; this is the
// least-squares axis of the known angles. Parameters: two small rotations of
// the direction, two shifts of the point across it, and the centres.
void refineAxis(const std::vector<const TargetView*>& main_views, TurntableAxis& axis,
                std::vector<Eigen::Vector3d>& centres) {
  const auto k_count = static_cast<Eigen::Index>(centres.size());
  const Eigen::Index n_params = 4 + 3 * k_count;
  const auto n_residuals = static_cast<Eigen::Index>(3 * main_views.size() * centres.size());
  const auto unpack = [&](const Eigen::VectorXd& x, TurntableAxis& a,
                          std::vector<Eigen::Vector3d>& c) {
    const Eigen::Vector3d e1 = axis.direction.unitOrthogonal();
    const Eigen::Vector3d e2 = axis.direction.cross(e1);
    a.direction = (axis.direction + x(0) * e1 + x(1) * e2).normalized();
    a.point = axis.point + x(2) * e1 + x(3) * e2;
    c = centres;
    for (Eigen::Index k = 0; k < k_count; ++k)
      c[static_cast<std::size_t>(k)] += x.segment<3>(4 + 3 * k);
  };
  const auto residuals = [&](const Eigen::VectorXd& x) {
    TurntableAxis a;
    std::vector<Eigen::Vector3d> c;
    unpack(x, a, c);
    Eigen::VectorXd r(n_residuals);
    Eigen::Index at = 0;
    for (const TargetView* view : main_views) {
      const RigidPose t = a.turn(view->turn_deg);
      for (std::size_t k = 0; k < c.size(); ++k, at += 3)
        r.segment<3>(at) = t.apply(c[k]) - view->centres[k];
    }
    return r;
  };
  for (int iteration = 0; iteration < 10; ++iteration) {
    const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(n_params);
    const Eigen::VectorXd r0 = residuals(x0);
    Eigen::MatrixXd jacobian(n_residuals, n_params);
    for (Eigen::Index p = 0; p < n_params; ++p) {
      const double h = p < 2 ? 1e-7 : 1e-5;  // rad, mm
      Eigen::VectorXd plus = x0, minus = x0;
      plus(p) += h;
      minus(p) -= h;
      jacobian.col(p) = (residuals(plus) - residuals(minus)) / (2 * h);
    }
    // The point along the axis is free (not a parameter); the rest is determined.
    const Eigen::VectorXd step = jacobian.colPivHouseholderQr().solve(-r0);
    TurntableAxis next;
    std::vector<Eigen::Vector3d> next_centres;
    unpack(step, next, next_centres);
    next.point -= next.direction.dot(next.point) * next.direction;
    axis = next;
    centres = next_centres;
    if (step.head<2>().norm() < 1e-12 && step.tail(n_params - 2).norm() < 1e-9) break;
  }
}

}  // namespace

RigidPose TurntableAxis::turn(double deg) const {
  RigidPose pose;
  pose.R = Eigen::AngleAxisd(deg * kDegToRad, direction.normalized()).toRotationMatrix();
  pose.T = point - pose.R * point;
  return pose;
}

RigidPose fitRigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                   std::string_view what) {
  if (from.size() != to.size()) {
    throw std::invalid_argument("rigid fit of " + std::string(what) + ": " +
                                std::to_string(from.size()) + " points against " +
                                std::to_string(to.size()));
  }
  if (from.size() < 3) {
    throw std::invalid_argument("rigid fit of " + std::string(what) + ": needs 3 points, has " +
                                std::to_string(from.size()));
  }
  const Eigen::Matrix3Xd a = columns(from);
  const Eigen::Matrix3Xd b = columns(to);
  if (collinear(a) || collinear(b)) {
    throw std::invalid_argument("rigid fit of " + std::string(what) +
                                ": the points are collinear (the rotation about their line is "
                                "not determined)");
  }
  const Eigen::Matrix4d m = Eigen::umeyama(a, b, false);
  RigidPose pose;
  pose.R = m.topLeftCorner<3, 3>();
  pose.T = m.topRightCorner<3, 1>();
  return pose;
}

std::vector<Eigen::Vector3d> matchTargetOrder(std::span<const Eigen::Vector3d> reference,
                                              std::span<const Eigen::Vector3d> centres) {
  if (reference.size() != centres.size()) {
    throw std::invalid_argument("target order: " + std::to_string(centres.size()) +
                                " centres against a reference of " +
                                std::to_string(reference.size()));
  }
  if (centres.size() > 8) {
    throw std::invalid_argument("target order: at most 8 spheres, not " +
                                std::to_string(centres.size()));
  }
  std::vector<std::size_t> order(centres.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<std::size_t> best = order;
  double best_rms = std::numeric_limits<double>::infinity();
  std::vector<Eigen::Vector3d> permuted(centres.size());
  do {
    for (std::size_t i = 0; i < order.size(); ++i)
      permuted[i] = centres[order[i]];
    const RigidPose pose = fitRigid(permuted, reference, "the target's centres");
    std::vector<double> errors;
    for (std::size_t i = 0; i < permuted.size(); ++i)
      errors.push_back((pose.apply(permuted[i]) - reference[i]).norm());
    const double rms = rmsOf(errors);
    if (rms < best_rms) {
      best_rms = rms;
      best = order;
    }
  } while (std::next_permutation(order.begin(), order.end()));
  for (std::size_t i = 0; i < best.size(); ++i)
    permuted[i] = centres[best[i]];
  return permuted;
}

HeadExtrinsicsSolution solveHeadExtrinsics(std::span<const TargetView> views,
                                           std::string_view reference_camera) {
  if (views.empty()) throw std::invalid_argument("head extrinsics: no views of the target");
  const std::size_t spheres = views.front().centres.size();
  std::vector<const TargetView*> main_views;
  std::map<std::string, std::vector<const TargetView*>, std::less<>> by_camera;
  for (const TargetView& view : views) {
    if (view.centres.size() != spheres) {
      throw std::invalid_argument("head extrinsics: " + describe(view) + " has " +
                                  std::to_string(view.centres.size()) +
                                  " sphere centres, the first view " + std::to_string(spheres));
    }
    if (collinear(columns(view.centres))) {
      throw std::invalid_argument("head extrinsics: the target's centres seen by " +
                                  describe(view) + " are collinear");
    }
    by_camera[view.camera].push_back(&view);
    if (view.camera == reference_camera) main_views.push_back(&view);
  }
  if (spheres < 3) {
    throw std::invalid_argument(
        "head extrinsics: the target needs 3 or more spheres, the views have " +
        std::to_string(spheres));
  }
  if (main_views.empty()) {
    throw std::invalid_argument("head extrinsics: no view of the target by the reference camera '" +
                                std::string(reference_camera) + "'");
  }

  HeadExtrinsicsSolution solution;
  solution.axis = fitAxis(main_views, solution.axis_angle_error_deg);

  // Step 2: the target at turn 0, head frame.
  solution.target_centres.assign(spheres, Eigen::Vector3d::Zero());
  for (const TargetView* view : main_views) {
    const RigidPose back = solution.axis.turn(-view->turn_deg);
    for (std::size_t k = 0; k < spheres; ++k)
      solution.target_centres[k] += back.apply(view->centres[k]);
  }
  for (Eigen::Vector3d& c : solution.target_centres)
    c /= static_cast<double>(main_views.size());
  refineAxis(main_views, solution.axis, solution.target_centres);

  const auto predicted = [&](double turn_deg) {
    const RigidPose turn = solution.axis.turn(turn_deg);
    std::vector<Eigen::Vector3d> out;
    for (const Eigen::Vector3d& c : solution.target_centres)
      out.push_back(turn.apply(c));
    return out;
  };

  // Step 3: every camera's pose from all its views.
  for (const auto& [camera, camera_views] : by_camera) {
    if (camera == reference_camera) {
      solution.poses[camera] = RigidPose{};
      continue;
    }
    std::vector<Eigen::Vector3d> from, to;
    for (const TargetView* view : camera_views) {
      const std::vector<Eigen::Vector3d> head = predicted(view->turn_deg);
      from.insert(from.end(), view->centres.begin(), view->centres.end());
      to.insert(to.end(), head.begin(), head.end());
    }
    solution.poses[camera] = fitRigid(from, to, "camera '" + camera + "'s view of the target");
  }

  // Residuals.
  std::vector<double> all;
  for (const auto& [camera, camera_views] : by_camera) {
    const RigidPose& pose = solution.poses.at(camera);
    std::vector<double> errors;
    for (const TargetView* view : camera_views) {
      const std::vector<Eigen::Vector3d> head = predicted(view->turn_deg);
      std::vector<double> view_errors;
      for (std::size_t k = 0; k < spheres; ++k)
        view_errors.push_back((pose.apply(view->centres[k]) - head[k]).norm());
      solution.views.push_back({camera, view->turn_deg, view->source, rmsOf(view_errors),
                                *std::max_element(view_errors.begin(), view_errors.end())});
      errors.insert(errors.end(), view_errors.begin(), view_errors.end());
    }
    CameraResidual residual;
    residual.rms_mm = rmsOf(errors);
    residual.max_mm = *std::max_element(errors.begin(), errors.end());
    residual.spheres = errors.size();
    residual.views = camera_views.size();
    solution.residuals[camera] = residual;
    all.insert(all.end(), errors.begin(), errors.end());
  }
  solution.rms_mm = rmsOf(all);
  solution.max_mm = *std::max_element(all.begin(), all.end());
  return solution;
}

}  // namespace cylscan::algo
