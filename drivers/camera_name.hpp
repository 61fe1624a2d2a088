// SPDX-License-Identifier: Apache-2.0
// The rule for a camera's name, on its own (no OpenCV, no TOML) so that the
// HTTP router and the store can check names without the board profile.
#pragma once

#include <algorithm>
#include <string_view>

namespace cylscan::drivers {

// A camera's name: 1 to 32 of [a-z0-9_-], starting with a letter or a digit.
// It names the camera's files (calibration/<name>.qcal, clouds/<name>.ply) and
// its URLs, so a board may only use names that are safe in both.
inline constexpr std::string_view kCameraNameRule =
    "1 to 32 of a-z 0-9 _ -, starting with a letter or a digit";

inline bool isCameraName(std::string_view name) {
  const auto lower_or_digit = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9');
  };
  if (name.empty() || name.size() > 32 || !lower_or_digit(name.front())) return false;
  return std::all_of(name.begin(), name.end(),
                     [&](char c) { return lower_or_digit(c) || c == '_' || c == '-'; });
}

}  // namespace cylscan::drivers
