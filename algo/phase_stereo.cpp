// SPDX-License-Identifier: Apache-2.0
#include "algo/phase_stereo.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/calib3d.hpp>

#include "algo/map_sampling.hpp"
#include "algo/numbers.hpp"

namespace cylscan::algo {
namespace {

void checkPhaseMap(const cv::Mat& phase, cv::Size size, const char* name) {
  if (phase.type() != CV_32FC1 || phase.size() != size)
    throw std::invalid_argument(std::string("phase stereo: the ") + name +
                                " phase map must be CV_32F of the calibrated image size");
}

}  // namespace

PhaseStereo::PhaseStereo(const StereoGeometry& geometry, PhaseStereoOptions options)
    : size_(geometry.main.image_size), options_(options) {
  if (size_.width < 2 || size_.height < 2) throw std::invalid_argument("phase stereo: empty image");
  if (geometry.aux.image_size != size_)
    throw std::invalid_argument("phase stereo: main and aux images differ in size");
  cv::Mat r1, r2, p1, p2, q;
  cv::stereoRectify(geometry.main.camera_matrix, geometry.main.dist_coeffs,
                    geometry.aux.camera_matrix, geometry.aux.dist_coeffs, size_,
                    cv::Mat(geometry.rotation), cv::Mat(geometry.translation), r1, r2, p1, p2, q, 0,
                    options.alpha, size_);  // not CALIB_ZERO_DISPARITY: a strongly
  // verged pair (the head's aux turns ~25°) would leave no overlap
  if (std::abs(p2.at<double>(1, 3)) > std::abs(p2.at<double>(0, 3)))
    throw std::invalid_argument("phase stereo: vertical stereo pairs are not supported");
  focal_ = p1.at<double>(0, 0);
  cx_main_ = p1.at<double>(0, 2);
  cy_ = p1.at<double>(1, 2);
  cx_aux_ = p2.at<double>(0, 2);
  p2_tx_ = p2.at<double>(0, 3);
  rect_to_main_ = cv::Matx33d(r1).t();

  std::vector<cv::Point2d> pixels;
  pixels.reserve(static_cast<std::size_t>(size_.area()));
  for (int v = 0; v < size_.height; ++v)
    for (int u = 0; u < size_.width; ++u)
      pixels.emplace_back(u, v);
  std::vector<cv::Point2d> rectified;
  cv::undistortPoints(
      pixels, rectified, geometry.main.camera_matrix, geometry.main.dist_coeffs, r1, p1,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  main_rectified_.create(size_, CV_64FC2);
  std::size_t i = 0;
  for (int v = 0; v < size_.height; ++v) {
    auto* row = main_rectified_.ptr<cv::Vec2d>(v);
    for (int u = 0; u < size_.width; ++u, ++i)
      row[u] = cv::Vec2d(rectified[i].x, rectified[i].y);
  }
  cv::initUndistortRectifyMap(geometry.aux.camera_matrix, geometry.aux.dist_coeffs, r2, p2, size_,
                              CV_32FC1, aux_map_x_, aux_map_y_);
}

cv::Mat PhaseStereo::rectifyAux(const cv::Mat& phase_aux) const {
  checkPhaseMap(phase_aux, size_, "aux");
  cv::Mat out(size_, CV_64FC1);
  for (int y = 0; y < size_.height; ++y) {
    const float* mx = aux_map_x_.ptr<float>(y);
    const float* my = aux_map_y_.ptr<float>(y);
    double* dst = out.ptr<double>(y);
    for (int x = 0; x < size_.width; ++x)
      dst[x] = sampleBilinear(phase_aux, mx[x], my[x]);
  }
  return out;
}

// Monotone segments of each rectified row (pairs = false) or of each pair of
// rows r, r+1 (pairs = true: both rows step the same way).
std::vector<std::vector<PhaseStereo::Segment>> PhaseStereo::segments(const cv::Mat& rectified,
                                                                     bool pairs) const {
  const int rows = pairs ? rectified.rows - 1 : rectified.rows;
  std::vector<std::vector<Segment>> out(static_cast<std::size_t>(rows));
  const double max_step = options_.max_phase_step_rad;
  // +1 rising, −1 falling, 0 no usable step, for one row.
  auto step = [&](const double* row, int x) {
    const double d = row[x + 1] - row[x];
    if (!std::isfinite(d) || std::abs(d) > max_step || d == 0.0) return 0;
    return d > 0.0 ? 1 : -1;
  };
  for (int r = 0; r < rows; ++r) {
    const double* a = rectified.ptr<double>(r);
    const double* b = pairs ? rectified.ptr<double>(r + 1) : a;
    std::vector<Segment>& list = out[static_cast<std::size_t>(r)];
    int open = 0;  // direction of the open segment, 0 if none
    for (int x = 0; x + 1 < rectified.cols; ++x) {
      const int sa = step(a, x);
      const int dir = sa != 0 && sa == step(b, x) ? sa : 0;
      if (dir != 0 && dir == open) {
        list.back().end = x + 1;
      } else if (dir != 0) {
        list.push_back(Segment{x, x + 1, dir > 0});
      }
      open = dir;
    }
  }
  return out;
}

PhaseStereoResult PhaseStereo::reconstruct(const cv::Mat& phase_main,
                                           const cv::Mat& phase_aux) const {
  checkPhaseMap(phase_main, size_, "main");
  const cv::Mat aux = rectifyAux(phase_aux);
  const auto single = segments(aux, false);
  const auto pairs = segments(aux, true);

  PhaseStereoResult result;
  result.xyz.create(size_, CV_32FC3);
  result.xyz.setTo(cv::Scalar::all(kNaNf));
  for (int v = 0; v < size_.height; ++v) {
    const float* phi_row = phase_main.ptr<float>(v);
    const auto* rect_row = main_rectified_.ptr<cv::Vec2d>(v);
    auto* out_row = result.xyz.ptr<cv::Vec3f>(v);
    for (int u = 0; u < size_.width; ++u) {
      const double phi = phi_row[u];
      const double xr = rect_row[u][0];
      const double yr = rect_row[u][1];
      if (!std::isfinite(phi) || !(yr >= 0.0 && yr <= size_.height - 1)) continue;
      int r = static_cast<int>(yr);
      double f = yr - r;
      if (r == size_.height - 1) {  // yr on the last row exactly
        r -= 1;
        f = 1.0;
      }
      const double* row0 = aux.ptr<double>(r);
      const double* row1 = aux.ptr<double>(r + 1);
      const bool blend = f > 0.0 && f < 1.0;
      const double* only = f >= 1.0 ? row1 : row0;
      auto value = [&](int x) { return blend ? (1.0 - f) * row0[x] + f * row1[x] : only[x]; };
      const std::vector<Segment>& list =
          blend ? pairs[static_cast<std::size_t>(r)]
                : single[static_cast<std::size_t>(f >= 1.0 ? r + 1 : r)];

      int matches = 0;
      double match_x = 0.0;
      for (const Segment& s : list) {
        // Orient so that the values rise from lo to hi.
        const double first = value(s.begin);
        const double last = value(s.end);
        const double lo_value = s.increasing ? first : last;
        const double hi_value = s.increasing ? last : first;
        if (!(phi >= lo_value && phi <= hi_value)) continue;
        int lo = s.begin;  // invariant: phi between value(lo) and value(hi)
        int hi = s.end;
        while (hi - lo > 1) {
          const int mid = lo + (hi - lo) / 2;
          const double vm = value(mid);
          if ((vm <= phi) == s.increasing) {
            lo = mid;
          } else {
            hi = mid;
          }
        }
        const double v_lo = value(lo);
        const double v_hi = value(hi);
        match_x = lo + (phi - v_lo) / (v_hi - v_lo);
        ++matches;
      }
      if (matches != 1) continue;  // no match, or ambiguous

      const double disparity = (xr - cx_main_) - (match_x - cx_aux_);
      const double z = -p2_tx_ / disparity;
      if (!(z > 0.0) || !std::isfinite(z)) continue;
      const cv::Vec3d rect((xr - cx_main_) * z / focal_, (yr - cy_) * z / focal_, z);
      const cv::Vec3d p = rect_to_main_ * rect;
      const cv::Point3f point(static_cast<float>(p[0]), static_cast<float>(p[1]),
                              static_cast<float>(p[2]));
      out_row[u] = cv::Vec3f(point.x, point.y, point.z);
      result.points.push_back(point);
      result.pixels.emplace_back(u, v);
    }
  }
  return result;
}

}  // namespace cylscan::algo
