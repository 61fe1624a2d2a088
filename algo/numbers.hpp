// SPDX-License-Identifier: Apache-2.0
// The constants that several computations share, defined once so that no two
// files of the project give the same name to two definitions.
#pragma once

#include <limits>
#include <numbers>

namespace cylscan::algo {

inline constexpr double kTwoPi = 2 * std::numbers::pi;
// Marks a value that has none (an invalid pixel, a fit that did not converge).
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

}  // namespace cylscan::algo
