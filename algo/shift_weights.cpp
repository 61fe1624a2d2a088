// SPDX-License-Identifier: Apache-2.0
#include "algo/shift_weights.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

#include "algo/numbers.hpp"

namespace cylscan::algo {
namespace {

// Shifts closer than this (in turns) count as the same shift.
constexpr double kSameShiftTurns = 1e-9;

[[noreturn]] void fail(std::string_view set_name, const std::string& why) {
  throw ShiftSolveError("the " + std::string(set_name) + " fringe set cannot be solved: " + why);
}

// Fraction of a turn in [0, 1).
double wrapTurns(double turns) {
  double r = turns - std::floor(turns);
  return r >= 1.0 ? 0.0 : r;
}

}  // namespace

CosSin reproducibleCosSinOfTurns(double turns) {
  // Reduce to the nearest quarter turn q and a remainder f in [-1/8, 1/8]; all exact.
  const double r = turns - std::floor(turns);
  const double q = std::floor(r * 4.0 + 0.5);
  const double f = r - q * 0.25;
  const double a = f * kTwoPi;  // |a| <= π/4
  const double a2 = a * a;
  // Taylor series to a^19 and a^20; the first omitted terms are below 2e-22 for |a| <= π/4.
  double s = 1.0 / 121645100408832000.0;  // 1/19!
  s = 1.0 / 355687428096000.0 - a2 * s;   // 1/17!
  s = 1.0 / 1307674368000.0 - a2 * s;     // 1/15!
  s = 1.0 / 6227020800.0 - a2 * s;        // 1/13!
  s = 1.0 / 39916800.0 - a2 * s;          // 1/11!
  s = 1.0 / 362880.0 - a2 * s;
  s = 1.0 / 5040.0 - a2 * s;
  s = 1.0 / 120.0 - a2 * s;
  s = 1.0 / 6.0 - a2 * s;
  s = a - a * a2 * s;
  double c = 1.0 / 2432902008176640000.0;  // 1/20!
  c = 1.0 / 6402373705728000.0 - a2 * c;   // 1/18!
  c = 1.0 / 20922789888000.0 - a2 * c;     // 1/16!
  c = 1.0 / 87178291200.0 - a2 * c;        // 1/14!
  c = 1.0 / 479001600.0 - a2 * c;
  c = 1.0 / 3628800.0 - a2 * c;
  c = 1.0 / 40320.0 - a2 * c;
  c = 1.0 / 720.0 - a2 * c;
  c = 1.0 / 24.0 - a2 * c;
  c = 0.5 - a2 * c;
  c = 1.0 - a2 * c;
  switch (static_cast<int>(q) & 3) {
    case 0:
      return {c, s};
    case 1:
      return {-s, c};
    case 2:
      return {-c, -s};
    default:
      return {s, -c};
  }
}

ShiftWeights::ShiftWeights(const FringeSetGeometry& geometry, std::string_view set_name)
    : ShiftWeights(
          [&] {
            const double period = geometry.period_deg;
            if (!std::isfinite(period) || period <= 0) {
              std::ostringstream msg;
              msg << "period_deg is " << period << "; it must be a positive number of degrees";
              fail(set_name, msg.str());
            }
            std::vector<double> turns;
            turns.reserve(geometry.stage_deg.size());
            for (std::size_t k = 0; k < geometry.stage_deg.size(); ++k) {
              const double stage = geometry.stage_deg[k];
              if (!std::isfinite(stage)) {
                fail(set_name, "stage_deg[" + std::to_string(k) + "] is not a finite angle");
              }
              turns.push_back((stage - geometry.stage_deg[0]) / period);
            }
            return turns;
          }(),
          set_name) {}

ShiftWeights ShiftWeights::fromTurns(std::span<const double> turns, std::string_view set_name) {
  for (std::size_t k = 0; k < turns.size(); ++k) {
    if (!std::isfinite(turns[k])) {
      fail(set_name, "shift " + std::to_string(k) + " is not finite");
    }
  }
  return ShiftWeights(std::vector<double>(turns.begin(), turns.end()), set_name);
}

ShiftWeights::ShiftWeights(std::vector<double> turns, std::string_view set_name)
    : set_name_(set_name) {
  const std::size_t n = turns.size();
  if (n < 3) {
    fail(set_name, "it has " + std::to_string(n) +
                       " frames; at least 3 are needed for the three unknowns A, B, φ");
  }
  // Distinct shifts modulo one period.
  std::vector<double> wrapped(n);
  std::transform(turns.begin(), turns.end(), wrapped.begin(), wrapTurns);
  std::vector<double> sorted = wrapped;
  std::sort(sorted.begin(), sorted.end());
  std::size_t distinct = 1;
  for (std::size_t k = 1; k < n; ++k) {
    if (sorted[k] - sorted[k - 1] > kSameShiftTurns) ++distinct;
  }
  if (sorted.back() - sorted.front() > 1 - kSameShiftTurns && distinct > 1) --distinct;
  if (distinct == 1) {
    fail(set_name, "all " + std::to_string(n) +
                       " phase shifts are equal (mod 2π): the stage did not move within the set");
  }
  if (distinct < 3) {
    fail(set_name, "its " + std::to_string(n) +
                       " phase shifts take only 2 distinct values mod 2π; the normal matrix is "
                       "singular (at least 3 distinct shifts are needed)");
  }

  shifts_rad_.resize(n);
  cos_.resize(n);
  sin_.resize(n);
  double m[3][3] = {};
  for (std::size_t k = 0; k < n; ++k) {
    const CosSin cs = reproducibleCosSinOfTurns(wrapped[k]);
    shifts_rad_[k] = wrapped[k] * kTwoPi;
    cos_[k] = cs.cos;
    sin_[k] = cs.sin;
    const double r[3] = {1.0, cs.cos, cs.sin};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        m[i][j] += r[i] * r[j];
    }
  }

  Eigen::Matrix3d em;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      em(i, j) = m[i][j];
  }
  const Eigen::Vector3d eig = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(em).eigenvalues();
  condition_number_ = eig(0) > 0 ? eig(2) / eig(0) : std::numeric_limits<double>::infinity();
  if (!(condition_number_ <= kMaxConditionNumber)) {
    std::ostringstream msg;
    msg << "its normal matrix is ill-conditioned (condition number " << condition_number_ << " > "
        << kMaxConditionNumber
        << "): the shifts span too small a part of the period to separate A, B and φ";
    fail(set_name, msg.str());
  }

  // M⁻¹ by cofactors, in a fixed order of IEEE operations (reproducible bits).
  const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  const double c11 = m[0][0] * m[2][2] - m[0][2] * m[2][0];
  const double c12 = m[0][1] * m[2][0] - m[0][0] * m[2][1];
  const double c22 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  const double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
  const double inv[3][3] = {{c00 / det, c01 / det, c02 / det},
                            {c01 / det, c11 / det, c12 / det},
                            {c02 / det, c12 / det, c22 / det}};

  frames_.resize(n);
  double gain = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double r[3] = {1.0, cos_[k], sin_[k]};
    double w[3];
    for (int i = 0; i < 3; ++i)
      w[i] = inv[i][0] * r[0] + inv[i][1] * r[1] + inv[i][2] * r[2];
    frames_[k] = {w[0], w[1], w[2]};
    gain += w[1] * w[1] + w[2] * w[2];
  }
  noise_gain_ = gain / 2;
}

}  // namespace cylscan::algo
