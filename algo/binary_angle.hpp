// SPDX-License-Identifier: Apache-2.0
// Phase as a binary angle and an atan2 that gives the same bits on every IEEE-754 CPU.
//
// A BinaryAngle is a uint16 fraction of a turn (65536 = 2π), so wrapping is the
// natural uint16 overflow and differences of phases need no branch.
//
// binaryAtan2 reduces (C, S) to the first octant, forms t = min/max with one
// IEEE-754 single-precision division (correctly rounded, hence the same bits on
// every IEEE CPU: x86 SSE/AVX, ARM VFP/NEON), and evaluates an odd minimax
// polynomial of atan in t with single-precision multiplies and subtractions in a
// fixed order (Horner in u = t², no fused multiply-add: the build sets
// -ffp-contract=off), then unfolds the octant in integers. Float arithmetic here
// is cheaper than a 32-bit fixed-point Horner: a vector float multiply is one
// operation, a 32-bit integer multiply two, and t needs no quantising step.
// Max error against the exact atan2 is below 1 LSB (2π/65536 ≈ 9.6e-5 rad);
// tests measure it.
#pragma once

#include <cstdint>
#include <numbers>

namespace cylscan::algo {

using BinaryAngle = std::uint16_t;

inline constexpr double kBinaryAnglesPerTurn = 65536.0;
inline constexpr double kRadiansPerBinaryAngle = 2 * std::numbers::pi / kBinaryAnglesPerTurn;

constexpr double binaryAngleToRadians(BinaryAngle a) {
  return a * kRadiansPerBinaryAngle;
}

namespace binary_angle_detail {
// Coefficients of atan(t) / t in units of 2^-19 turn:
// atan(t)·2^19/(2π) ≈ t·(c1 − u·(c3 − u·(c5 − u·(c7 − u·c9)))), u = t². Fitted
// (minimax, Lawson iterations) to the octant t ∈ [0, 1].
inline constexpr float kC1 = 83432.0f;
inline constexpr float kC3 = 27562.0f;
inline constexpr float kC5 = 15033.0f;
inline constexpr float kC7 = 7106.0f;
inline constexpr float kC9 = 1739.0f;
}  // namespace binary_angle_detail

// atan of t ∈ [0, 1], rounded to units of 2^-19 turn (so [0, 2^16] for the octant).
inline std::uint32_t octantAtan(float t) {
  using namespace binary_angle_detail;
  const float u = t * t;
  float p = kC7 - u * kC9;
  p = kC5 - u * p;
  p = kC3 - u * p;
  p = kC1 - u * p;
  // t·p is in [0, 65537): adding a half and truncating rounds it, in float
  // operations that give the same bits everywhere (std::lround would call the
  // C library).
  return static_cast<std::uint32_t>(
      static_cast<std::int32_t>(t * p + 0.5f));  // NOLINT(bugprone-incorrect-roundings)
}

// A point (c, s) in polar form: its binary angle and its magnitude.
struct BinaryPolar {
  BinaryAngle angle = 0;
  float magnitude = 0;  // hypot(c, s), relative error < 1e-5
};

// atan2(s, c) as a binary angle in [0, 2π), and hypot(c, s). Defined for every int32
// pair except INT32_MIN (callers keep |c|, |s| < 2^31); the angle of (0, 0) is 0.
// Branch-free (masks, min/max) so that loops over it vectorise.
inline BinaryPolar binaryPolar(std::int32_t s, std::int32_t c) {
  const auto uc = static_cast<std::uint32_t>(c);
  const auto us = static_cast<std::uint32_t>(s);
  const std::uint32_t neg_c = 0u - (uc >> 31);  // all ones when c < 0
  const std::uint32_t neg_s = 0u - (us >> 31);
  const std::uint32_t ax = (uc ^ neg_c) - neg_c;  // |c|
  const std::uint32_t ay = (us ^ neg_s) - neg_s;  // |s|
  const std::uint32_t steep = 0u - static_cast<std::uint32_t>(ay > ax);
  const std::uint32_t num = ax < ay ? ax : ay;
  std::uint32_t den = ax < ay ? ay : ax;
  den = den > 1u ? den : 1u;
  // The one division: IEEE-754 single precision, correctly rounded, reproducible.
  const float den_f = static_cast<float>(static_cast<std::int32_t>(den));
  const float ratio = static_cast<float>(static_cast<std::int32_t>(num)) / den_f;
  std::uint32_t a = octantAtan(ratio);  // 2^-19 turn, [0, 2^16]
  a += steep & ((1u << 17) - 2 * a);    // steep: a quarter turn minus a
  a += neg_c & ((1u << 18) - 2 * a);    // c < 0: half a turn minus a
  a += neg_s & ((1u << 19) - 2 * a);    // s < 0: a full turn minus a
  // hypot = den·sqrt(1 + ratio²): a minimax polynomial in ratio² (relative error
  // 8.4e-6), IEEE float multiplies and adds in a fixed order, no sqrt.
  const float u = ratio * ratio;
  float h = -1.073661392e-02f;
  h = h * u + 4.562749223e-02f;
  h = h * u - 1.201945410e-01f;
  h = h * u + 4.994970447e-01f;
  h = h * u + 1.000008355e+00f;
  return {static_cast<BinaryAngle>((a + 4) >> 3), den_f * h};
}

// atan2(s, c) as a binary angle in [0, 2π); see binaryPolar.
inline BinaryAngle binaryAtan2(std::int32_t s, std::int32_t c) {
  return binaryPolar(s, c).angle;
}

}  // namespace cylscan::algo
