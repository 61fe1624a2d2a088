// SPDX-License-Identifier: Apache-2.0
#include "tools/report_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace cylscan::tools {
namespace {

// Colours as functions, not globals: cv::Scalar's constructor may throw, and a
// throwing static initialiser cannot be caught (cert-err58-cpp).
cv::Scalar black() {
  return {0, 0, 0};
}
cv::Scalar white() {
  return {255, 255, 255};
}
cv::Scalar noData() {
  return {215, 215, 215};
}
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// Blue (−) → white (0) → red (+), as a 256-entry LUT for cv::applyColorMap.
cv::Mat divergingLut() {
  cv::Mat lut(256, 1, CV_8UC3);
  const cv::Vec3d blue(180, 60, 30), white(255, 255, 255), red(40, 40, 200);  // BGR
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0 * 2 - 1;
    const cv::Vec3d c = t < 0 ? white + (blue - white) * (-t) : white + (red - white) * t;
    lut.at<cv::Vec3b>(i) = cv::Vec3b(cv::saturate_cast<uchar>(c[0]), cv::saturate_cast<uchar>(c[1]),
                                     cv::saturate_cast<uchar>(c[2]));
  }
  return lut;
}

std::string format(double value, const char* pattern) {
  char text[64];
  std::snprintf(text, sizeof text, pattern, value);
  return text;
}

void putLabel(cv::Mat& image, const std::string& text, cv::Point at, double scale = 0.45,
              int thickness = 1) {
  cv::putText(image, text, at, kFont, scale, black(), thickness, cv::LINE_AA);
}

int textWidth(const std::string& text, double scale = 0.45) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, 1, &baseline).width;
}

// A colour code of t in [−1, 1], in kLevels steps (discrete bands read
// better and compress far better than a continuous noisy ramp).
constexpr int kLevels = 24;
uchar quantised(double t) {
  const int level = std::clamp(static_cast<int>(std::floor((t + 1) / 2 * kLevels)), 0, kLevels - 1);
  return cv::saturate_cast<uchar>((level + 0.5) * 256.0 / kLevels);
}

// The panel's errors as colours on ±scale, grey where there is no point.
cv::Mat colourPanel(const cv::Mat& error, double scale, const cv::Mat& lut) {
  cv::Mat codes(error.size(), CV_8U);
  cv::Mat missing(error.size(), CV_8U);
  for (int v = 0; v < error.rows; ++v) {
    const float* e = error.ptr<float>(v);
    for (int u = 0; u < error.cols; ++u) {
      const bool finite = std::isfinite(e[u]);
      const double t = finite ? std::clamp(e[u] / scale, -1.0, 1.0) : 0.0;
      codes.at<uchar>(v, u) = quantised(t);
      missing.at<uchar>(v, u) = finite ? 0 : 255;
    }
  }
  cv::Mat colour;
  cv::applyColorMap(codes, colour, lut);
  colour.setTo(noData(), missing);
  return colour;
}

// The map shrunk to `size`: each output pixel is the mean of the finite
// errors it covers, NaN where fewer than half of them are finite.
cv::Mat averaged(const cv::Mat& error, cv::Size size) {
  cv::Mat finite = (error == error);  // NaN compares unequal
  cv::Mat values = error.clone();
  values.setTo(0.0f, ~finite);
  cv::Mat weight;
  finite.convertTo(weight, CV_32F, 1.0 / 255);
  cv::Mat sum, count;
  cv::resize(values, sum, size, 0, 0, cv::INTER_AREA);
  cv::resize(weight, count, size, 0, 0, cv::INTER_AREA);
  cv::Mat out = sum / cv::max(count, 1e-6f);
  out.setTo(std::numeric_limits<float>::quiet_NaN(), count < 0.5f);
  return out;
}

}  // namespace

double symmetricScale(const std::vector<ErrorMapPanel>& panels) {
  std::vector<float> magnitudes;
  for (const auto& p : panels) {
    for (auto it = p.error_mm.begin<float>(); it != p.error_mm.end<float>(); ++it) {
      if (std::isfinite(*it)) magnitudes.push_back(std::abs(*it));
    }
  }
  if (magnitudes.empty()) return 0.1;
  const auto k = static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(magnitudes.size() - 1));
  std::nth_element(magnitudes.begin(), magnitudes.begin() + k, magnitudes.end());
  const double p99 = std::max(static_cast<double>(magnitudes[static_cast<std::size_t>(k)]), 0.01);
  const double decade = std::pow(10.0, std::floor(std::log10(p99)));
  for (double step : {1.0, 2.0, 5.0, 10.0}) {
    if (p99 <= step * decade * (1 + 1e-9)) return step * decade;
  }
  return 10 * decade;
}

cv::Mat drawErrorMaps(const std::vector<ErrorMapPanel>& panels, double scale_mm,
                      const std::string& title, int panel_width) {
  if (panels.empty() || !(scale_mm > 0))
    throw std::invalid_argument("error maps: no panel or no scale");
  const cv::Size grid = panels.front().error_mm.size();
  const int panel_height = panel_width * grid.height / grid.width;
  const int margin = 12, top = 56, bar_width = 18, bar_area = 110;
  const int width = margin + static_cast<int>(panels.size()) * (panel_width + margin) + bar_area;
  const int height = top + panel_height + 36;
  cv::Mat canvas(height, width, CV_8UC3, white());
  putLabel(canvas, title, {margin, 22}, 0.55, 1);
  const cv::Mat lut = divergingLut();
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const int x = margin + static_cast<int>(i) * (panel_width + margin);
    // Cells of 2 × 2 drawn pixels: the mean of ~30 main pixels at full
    // resolution shows the systematic pattern through the noise.
    cv::Mat cells = colourPanel(averaged(panels[i].error_mm, {panel_width / 2, panel_height / 2}),
                                scale_mm, lut);
    cv::resize(cells, canvas(cv::Rect(x, top, panel_width, panel_height)),
               {panel_width, panel_height}, 0, 0, cv::INTER_NEAREST);
    cv::rectangle(canvas, cv::Rect(x - 1, top - 1, panel_width + 2, panel_height + 2), black());
    putLabel(canvas, panels[i].title, {x, top - 8});
  }
  // Colour bar: +scale at the top, −scale at the bottom.
  const int bx = width - bar_area + 14;
  for (int y = 0; y < panel_height; ++y) {
    const cv::Vec3b& c = lut.at<cv::Vec3b>(quantised(1.0 - 2.0 * y / (panel_height - 1)));
    cv::line(canvas, {bx, top + y}, {bx + bar_width, top + y}, cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(canvas, cv::Rect(bx - 1, top - 1, bar_width + 2, panel_height + 2), black());
  for (int k = -2; k <= 2; ++k) {
    const int y = top + static_cast<int>(std::lround((panel_height - 1) * (2 - k) / 4.0));
    cv::line(canvas, {bx + bar_width, y}, {bx + bar_width + 5, y}, black());
    putLabel(canvas, format(scale_mm * k / 2, "%+.3g"), {bx + bar_width + 8, y + 5}, 0.4);
  }
  putLabel(canvas, "mm", {bx, top + panel_height + 20}, 0.45);
  putLabel(canvas,
           "signed distance to the true surface at the main pixels (u, v), mean per cell; "
           "grey: no point",
           {margin, top + panel_height + 22}, 0.42);
  return canvas;
}

cv::Mat drawHistograms(const std::vector<HistogramSeries>& series, double range_mm, int bins,
                       const std::string& title, const std::string& x_label) {
  if (series.empty() || bins < 2 || !(range_mm > 0))
    throw std::invalid_argument("histogram: no series, bins or range");
  std::vector<std::vector<double>> fractions;
  double peak = 0;
  for (const auto& s : series) {
    std::vector<double> f(static_cast<std::size_t>(bins), 0.0);
    for (double v : s.values_mm) {
      const int b = static_cast<int>(std::floor((v + range_mm) / (2 * range_mm) * bins));
      f[static_cast<std::size_t>(std::clamp(b, 0, bins - 1))] += 1.0;
    }
    const double n = std::max<double>(1.0, static_cast<double>(s.values_mm.size()));
    for (double& x : f)
      x /= n;
    peak = std::max(peak, *std::max_element(f.begin(), f.end()));
    fractions.push_back(std::move(f));
  }
  peak = std::max(peak * 1.1, 1e-6);
  const int left = 70, right = 20, top = 40, bottom = 56, plot_w = 560, plot_h = 300;
  cv::Mat canvas(top + plot_h + bottom, left + plot_w + right, CV_8UC3, white());
  putLabel(canvas, title, {left, 24}, 0.55);
  const cv::Rect plot(left, top, plot_w, plot_h);
  auto xOf = [&](double mm) {
    return left + static_cast<int>(std::lround((mm + range_mm) / (2 * range_mm) * plot_w));
  };
  auto yOf = [&](double f) {
    return top + plot_h - static_cast<int>(std::lround(f / peak * plot_h));
  };
  // Axes, ticks and labels.
  for (int k = -4; k <= 4; ++k) {
    const double mm = range_mm * k / 4;
    const int x = xOf(mm);
    cv::line(canvas, {x, top + plot_h}, {x, top + plot_h + 5}, black());
    const std::string t = format(mm, "%.3g");
    putLabel(canvas, t, {x - textWidth(t, 0.4) / 2, top + plot_h + 20}, 0.4);
  }
  for (int k = 0; k <= 4; ++k) {
    const double f = peak / 1.1 * k / 4;
    const int y = yOf(f);
    cv::line(canvas, {left - 5, y}, {left, y}, black());
    const std::string t = format(100 * f, "%.1f%%");
    putLabel(canvas, t, {left - 8 - textWidth(t, 0.4), y + 5}, 0.4);
  }
  putLabel(canvas, x_label, {left + plot_w / 2 - textWidth(x_label) / 2, top + plot_h + 44});
  cv::Mat vertical(20, 160, CV_8UC3, white());
  putLabel(vertical, "points per bin", {4, 15});
  cv::rotate(vertical, vertical, cv::ROTATE_90_COUNTERCLOCKWISE);
  vertical.copyTo(canvas(cv::Rect(2, top + plot_h / 2 - 80, 20, 160)));
  cv::line(canvas, {xOf(0), top}, {xOf(0), top + plot_h}, cv::Scalar(160, 160, 160));
  // One outline per series.
  for (std::size_t s = 0; s < series.size(); ++s) {
    std::vector<cv::Point> outline{{xOf(-range_mm), yOf(0)}};
    for (int b = 0; b < bins; ++b) {
      const double x0 = -range_mm + 2 * range_mm * b / bins;
      const double x1 = -range_mm + 2 * range_mm * (b + 1) / bins;
      const int y = yOf(fractions[s][static_cast<std::size_t>(b)]);
      outline.push_back({xOf(x0), y});
      outline.push_back({xOf(x1), y});
    }
    outline.push_back({xOf(range_mm), yOf(0)});
    cv::polylines(canvas, outline, false, series[s].colour, 2, cv::LINE_AA);
  }
  // Legend in a white box at the top right, over the curves.
  int label_width = 0;
  for (const auto& s : series)
    label_width = std::max(label_width, textWidth(s.label));
  const int lx = left + plot_w - label_width - 45;
  cv::rectangle(
      canvas, cv::Rect(lx - 6, top + 4, label_width + 45, 20 * static_cast<int>(series.size()) + 6),
      white(), cv::FILLED);
  for (std::size_t s = 0; s < series.size(); ++s) {
    const int ly = top + 18 + 20 * static_cast<int>(s);
    cv::line(canvas, {lx, ly - 4}, {lx + 25, ly - 4}, series[s].colour, 2);
    putLabel(canvas, series[s].label, {lx + 32, ly});
  }
  cv::rectangle(canvas, plot, black());
  return canvas;
}

}  // namespace cylscan::tools
