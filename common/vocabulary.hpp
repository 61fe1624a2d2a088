// SPDX-License-Identifier: Apache-2.0
// The words every layer shares, defined once: the two fringe sets, the phase
// a reconstruction uses, and the rule for a camera's name. Header-only and
// without dependencies, so algo/, formats/, drivers/, firmware/ and the HTTP
// router can all use it without depending on each other.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace cylscan {

// The two slot intervals of the cylinder: "high", the short interval θh (the
// fine fringes), and "low", the long one θl.
enum class FringeSet { High, Low };
inline constexpr std::array<FringeSet, 2> kFringeSets{FringeSet::High, FringeSet::Low};

constexpr std::string_view toString(FringeSet set) {
  return set == FringeSet::High ? "high" : "low";
}
constexpr std::optional<FringeSet> parseFringeSet(std::string_view name) {
  if (name == "high") return FringeSet::High;
  if (name == "low") return FringeSet::Low;
  return std::nullopt;
}

// The absolute phase a reconstruction uses: Φ of the high set unwrapped by the
// low one, or the fused Φ of both sets. The values are stored in the
// quasi-calibration file, so they never change.
enum class PhaseSource : std::uint32_t { High = 0, Fused = 1 };

constexpr std::string_view toString(PhaseSource source) {
  return source == PhaseSource::High ? "high" : "fused";
}
// std::invalid_argument naming the value for any other name.
inline PhaseSource parsePhaseSource(std::string_view name) {
  if (name == "high") return PhaseSource::High;
  if (name == "fused") return PhaseSource::Fused;
  throw std::invalid_argument("phase must be 'high' or 'fused', not '" + std::string(name) + "'");
}

// A camera's name: 1 to 32 of [a-z0-9_-], starting with a letter or a digit.
// It names the camera's files (calibration/<name>.qcal, clouds/<name>.ply), its
// sets in a capture bundle, its pose in head.json and its URLs, so a name must
// be safe in all of them.
inline constexpr std::string_view kCameraNameRule =
    "1 to 32 of a-z 0-9 _ -, starting with a letter or a digit";

constexpr bool isCameraName(std::string_view name) {
  const auto lower_or_digit = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9');
  };
  if (name.empty() || name.size() > 32 || !lower_or_digit(name.front())) return false;
  return std::all_of(name.begin(), name.end(),
                     [&](char c) { return lower_or_digit(c) || c == '_' || c == '-'; });
}

}  // namespace cylscan
