// SPDX-License-Identifier: Apache-2.0
#include "formats/rotation.hpp"

#include <cmath>
#include <cstdio>

#include <opencv2/core.hpp>

namespace cylscan::formats {
namespace {

std::string shortNumber(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

}  // namespace

std::optional<std::string> rotationFault(const cv::Matx33d& r) {
  const double orthogonality = cv::norm(r.t() * r - cv::Matx33d::eye(), cv::NORM_INF);
  if (!(orthogonality <= kRotationTolerance)) {
    return "is not a rotation: max |R^T R - I| = " + shortNumber(orthogonality) + " > " +
           shortNumber(kRotationTolerance);
  }
  const double det = cv::determinant(r);
  if (std::abs(det - 1) > kRotationTolerance) {
    return std::string(det < 0 ? "is a reflection" : "is not a rotation") +
           ": its determinant is " + shortNumber(det) + ", not +1";
  }
  return std::nullopt;
}

}  // namespace cylscan::formats
