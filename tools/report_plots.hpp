// SPDX-License-Identifier: Apache-2.0
// Figures of `cylscan study`, drawn with OpenCV: signed error maps on the main
// camera's pixel grid with a labelled colour bar, and overlaid histograms.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cylscan::tools {

struct ErrorMapPanel {
  std::string title;
  cv::Mat error_mm;  // CV_32F on the main pixel grid, NaN where there is no point
};

// The panels side by side, each shrunk to `panel_width` pixels in cells of
// 2 × 2 (each the mean error of the main pixels it covers), colour-mapped
// (blue-white-red) on the symmetric range ±scale_mm, with one colour bar.
cv::Mat drawErrorMaps(const std::vector<ErrorMapPanel>& panels, double scale_mm,
                      const std::string& title, int panel_width = 360);

struct HistogramSeries {
  std::string label;
  std::vector<double> values_mm;
  cv::Scalar colour;  // BGR
};

// Fractions of points per bin over [-range_mm, range_mm] (values outside are
// counted in the end bins), one outline per series, with axes and a legend.
cv::Mat drawHistograms(const std::vector<HistogramSeries>& series, double range_mm, int bins,
                       const std::string& title, const std::string& x_label);

// A symmetric colour scale for signed errors: the 99th percentile of |e| over
// all panels, rounded up to 1, 2 or 5 × 10^k (at least 0.01 mm).
double symmetricScale(const std::vector<ErrorMapPanel>& panels);

}  // namespace cylscan::tools
