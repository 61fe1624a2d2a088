// SPDX-License-Identifier: Apache-2.0
// Sampling a float map (e.g. an absolute-phase map) between its pixels.
#pragma once

#include <cmath>
#include <limits>

#include <opencv2/core.hpp>

namespace cylscan::algo {

// Bilinear sample of a CV_32F map at (x, y); NaN when outside the map or when
// a source pixel with non-zero weight is NaN.
inline double sampleBilinear(const cv::Mat& map, double x, double y) {
  if (!(x >= 0.0 && y >= 0.0 && x <= map.cols - 1 && y <= map.rows - 1))
    return std::numeric_limits<double>::quiet_NaN();
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const double fx = x - x0;
  const double fy = y - y0;
  const int x1 = fx > 0.0 ? x0 + 1 : x0;
  const int y1 = fy > 0.0 ? y0 + 1 : y0;
  const double a = map.at<float>(y0, x0);
  const double b = map.at<float>(y0, x1);
  const double c = map.at<float>(y1, x0);
  const double d = map.at<float>(y1, x1);
  if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c) || !std::isfinite(d))
    return std::numeric_limits<double>::quiet_NaN();
  return (1.0 - fy) * ((1.0 - fx) * a + fx * b) + fy * ((1.0 - fx) * c + fx * d);
}

}  // namespace cylscan::algo
