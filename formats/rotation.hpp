// SPDX-License-Identifier: Apache-2.0
// The one rule for a rotation matrix read from a file (stereo calibrations,
// head extrinsics).
#pragma once

#include <optional>
#include <string>

#include <opencv2/core/matx.hpp>

namespace cylscan::formats {

// |RᵀR − I| (largest element) a rotation read from a file may have: the
// files store 17 significant digits, so a real rotation is orders of
// magnitude closer, and a matrix farther off is not one.
inline constexpr double kRotationTolerance = 1e-6;

// Why r is not a rotation ("is not a rotation: …", "is a reflection: …"), or
// nullopt when it is one within kRotationTolerance.
std::optional<std::string> rotationFault(const cv::Matx33d& r);

}  // namespace cylscan::formats
