// SPDX-License-Identifier: Apache-2.0
#include "firmware/scan_plan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>

namespace cylscan::firmware {
namespace {

SetPlan planSet(FringeSet id, double period_deg, int frames, double start_deg,
                double steps_per_deg) {
  const std::string name(toString(id));
  if (frames < 3) throw std::invalid_argument("scan: the " + name + " set needs at least 3 frames");
  if (!(period_deg > 0))
    throw std::invalid_argument("scan: the " + name + " set's period must be positive");
  if (period_deg / frames * steps_per_deg < 1.0) {
    throw std::invalid_argument("scan: the " + name + " set's frame step (" +
                                std::to_string(period_deg / frames) +
                                " deg) is finer than one stage step");
  }
  SetPlan plan;
  plan.set = id;
  plan.period_deg = period_deg;
  plan.step_deg = period_deg / frames;
  const auto start = std::llround(start_deg * steps_per_deg);
  for (int k = 0; k < frames; ++k)
    plan.positions.push_back(start + std::llround(k * period_deg / frames * steps_per_deg));
  return plan;
}

std::string fmt(double v, int precision = 3) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(precision);
  out << v;
  return out.str();
}

bool wholeNumber(double x) {
  return std::abs(x - std::round(x)) < 1e-9 * std::max(1.0, std::abs(x));
}

double floorMod(double x, double m) {
  return x - m * std::floor(x / m);
}

// The margin of the interval [lo, hi] from the points origin + k·spacing: the
// distance to the nearest one when none is inside, minus the overlap when one is.
double marginFromGrid(double lo, double hi, double origin, double spacing) {
  const double k = std::floor((lo - origin) / spacing);
  const double left = origin + k * spacing;  // the grid point at or below lo
  const double right = left + spacing;
  if (hi < right) return std::min(lo - left, right - hi);
  return -(hi - right);  // the interval crosses a grid point
}

std::vector<double> shiftsOf(int frames, std::int64_t step_steps, double steps_per_deg,
                             double period_deg) {
  std::vector<double> shifts;
  shifts.reserve(static_cast<std::size_t>(std::max(frames, 0)));
  for (int k = 0; k < frames; ++k) {
    shifts.push_back(2.0 * std::numbers::pi * static_cast<double>(k * step_steps) / steps_per_deg /
                     period_deg);
  }
  return shifts;
}

struct CameraGeometry {
  std::string name;
  double lo = 0, hi = 0;
};

struct RingScore {
  double score = -std::numeric_limits<double>::infinity();
  std::vector<RingCamera> cameras;
  std::string limiting;  // the camera with the least margin
};

RingScore scoreRing(const std::vector<CameraGeometry>& cameras, double start_deg, double span_deg,
                    double h0, double lambda_eq) {
  RingScore s;
  s.score = std::numeric_limits<double>::infinity();
  for (const auto& c : cameras) {
    RingCamera rc;
    rc.camera = c.name;
    // Wall angles β = a − ρ at the sweep's first frame, and over the sweep (ρ
    // grows by the span, so β falls by it). Sweep 2 is 180° away: the same
    // margins, since both grids repeat every 180°.
    const double lo = c.lo - start_deg, hi = c.hi - start_deg;
    rc.window_margin_deg = marginFromGrid(lo, hi, h0, lambda_eq);
    rc.half_margin_deg = marginFromGrid(lo - span_deg, hi, h0, 180.0);
    rc.first_sweep_set =
        floorMod(lo - span_deg - h0, 360.0) < 180.0 ? FringeSet::High : FringeSet::Low;
    const double m = std::min(rc.window_margin_deg, rc.half_margin_deg);
    if (m < s.score) {
      s.score = m;
      s.limiting = c.name;
    }
    s.cameras.push_back(rc);
  }
  return s;
}

void planRing(const ScanOptions& o, ScanPlan& plan) {
  const double spd = plan.steps_per_deg;
  const double th = o.period_high_deg, tl = o.period_low_deg;
  if (o.frames_high != o.frames_low) {
    throw std::invalid_argument("scan: a ring plan sweeps both sets with the same frames (high " +
                                std::to_string(o.frames_high) + ", low " +
                                std::to_string(o.frames_low) + ")");
  }
  const int n = o.frames_high;
  if (n < 3) throw std::invalid_argument("scan: a ring plan needs at least 3 frames a sweep");
  if (!(th > 0) || !(tl > 0) || th == tl)
    throw std::invalid_argument("scan: the ring plan needs two different positive periods");
  const double lambda_eq = th * tl / std::abs(tl - th);
  // Each half must hold whole periods of its slots and whole equivalent
  // periods, so that the two sweeps 180° apart see the same fringe origin.
  if (!wholeNumber(180.0 / th) || !wholeNumber(180.0 / tl) || !wholeNumber(180.0 / lambda_eq)) {
    throw std::invalid_argument(
        "scan: a ring plan needs whole numbers of periods on each half (180/" + fmt(th) + ", 180/" +
        fmt(tl) + " and 180/" + fmt(lambda_eq) + " are not all whole)");
  }
  if (!wholeNumber(180.0 * spd))
    throw std::invalid_argument(
        "scan: a ring plan needs 180 deg to be a whole number of stage steps");
  const auto half_turn = std::llround(180.0 * spd);

  std::vector<CameraGeometry> cameras;
  for (const auto& name : o.cameras) {
    const auto it = std::find_if(o.azimuths.begin(), o.azimuths.end(),
                                 [&](const CameraAzimuth& a) { return a.camera == name; });
    if (it == o.azimuths.end()) {
      throw std::invalid_argument("scan: camera '" + name +
                                  "' has no azimuth_deg: the ring plan needs each camera's working "
                                  "volume in projector azimuth");
    }
    if (!(it->lo_deg < it->hi_deg))
      throw std::invalid_argument("scan: camera '" + name + "': azimuth_deg needs lo < hi");
    cameras.push_back({name, it->lo_deg, it->hi_deg});
  }
  if (cameras.empty()) throw std::invalid_argument("scan: a ring plan needs cameras");
  const double margin = o.ring_margin_deg;

  // The frame step Δ, in whole motor steps: given, or the one that makes the
  // worse of the two sets' noise gains least (a high set stepped by Δ sees
  // 2πΔ/θh a frame, a low set 2πΔ/θl).
  std::int64_t step = 0;
  double gain_high = 0, gain_low = 0;
  auto gains = [&](std::int64_t s) {
    return std::pair{phaseNoiseGain(shiftsOf(n, s, spd, th)),
                     phaseNoiseGain(shiftsOf(n, s, spd, tl))};
  };
  if (o.step_deg > 0) {
    step = std::llround(o.step_deg * spd);
    if (step < 1)
      throw std::invalid_argument("scan: step_deg (" + fmt(o.step_deg, 5) +
                                  ") is finer than one stage step");
    std::tie(gain_high, gain_low) = gains(step);
  } else {
    const auto lo = std::max<std::int64_t>(1, std::llround(std::floor(0.5 * th / n * spd)));
    const auto hi = std::max<std::int64_t>(lo, std::llround(std::ceil(1.5 * tl / n * spd)));
    double best = std::numeric_limits<double>::infinity();
    for (auto s = lo; s <= hi; ++s) {
      const auto [gh, gl] = gains(s);
      if (std::max(gh, gl) < best - 1e-12) {
        best = std::max(gh, gl);
        step = s;
        gain_high = gh;
        gain_low = gl;
      }
    }
  }
  // A set whose shifts are nearly alike (too small a step, or a whole number
  // of periods between frames) cannot be fitted: refuse rather than scan noise.
  constexpr double kMaxNoiseGain = 2.0;
  if (!(std::max(gain_high, gain_low) <= kMaxNoiseGain)) {
    throw std::invalid_argument(
        "scan: with a frame step of " + fmt(static_cast<double>(step) / spd, 4) + " deg and " +
        std::to_string(n) + " frames the " + (gain_high > gain_low ? "high" : "low") +
        " set's shifts are ill-conditioned (phase noise " + fmt(std::max(gain_high, gain_low), 2) +
        " times the ideal; at most " + fmt(kMaxNoiseGain, 1) + ")");
  }
  const double step_deg = static_cast<double>(step) / spd;
  const double span = (n - 1) * step_deg;

  // Cameras that cannot fit whatever the start.
  for (const auto& c : cameras) {
    const double width = c.hi - c.lo;
    if (width + 2 * margin > lambda_eq) {
      throw std::invalid_argument("scan: camera '" + c.name + "''s working volume spans " +
                                  fmt(width, 2) + " deg of azimuth (" + fmt(c.lo, 2) + " .. " +
                                  fmt(c.hi, 2) + "): more than one equivalent period (" +
                                  fmt(lambda_eq, 2) + " deg) less the margins (2 x " +
                                  fmt(margin, 2) + ")");
    }
  }

  // The start: every whole step of a turn, main on the high half in sweep 1;
  // the one that leaves the most room to the nearest wrap or boundary.
  RingScore best;
  std::int64_t best_start = -1;
  const auto turn = 2 * half_turn;
  for (std::int64_t p = 0; p < turn; ++p) {
    const double rho = static_cast<double>(p) / spd;
    RingScore s = scoreRing(cameras, rho, span, o.high_half_start_deg, lambda_eq);
    if (s.cameras.front().first_sweep_set != FringeSet::High && cameras.front().name == "main") {
      continue;
    }
    if (s.score > best.score + 1e-12) {
      best = std::move(s);
      best_start = p;
    }
  }
  if (best_start < 0 || best.score < margin) {
    const auto it = std::find_if(best.cameras.begin(), best.cameras.end(),
                                 [&](const RingCamera& c) { return c.camera == best.limiting; });
    std::string why;
    if (it != best.cameras.end()) {
      why = it->window_margin_deg < it->half_margin_deg
                ? (it->window_margin_deg < 0 ? "straddles an equivalent-period wrap by " +
                                                   fmt(-it->window_margin_deg, 2) + " deg"
                                             : "is " + fmt(it->window_margin_deg, 2) +
                                                   " deg from an equivalent-period wrap")
                : (it->half_margin_deg < 0
                       ? "straddles a half boundary by " + fmt(-it->half_margin_deg, 2) +
                             " deg during its sweep"
                       : "is " + fmt(it->half_margin_deg, 2) +
                             " deg from a half boundary during its sweep");
    }
    throw std::invalid_argument(
        "scan: no ring start keeps every camera's working volume inside one equivalent period (" +
        fmt(lambda_eq, 2) + " deg) and off the half boundaries with " + fmt(margin, 2) +
        " deg to spare: at the best start (" + fmt(static_cast<double>(best_start) / spd, 3) +
        " deg) camera '" + best.limiting + "' " + why);
  }

  const std::int64_t start2 =
      best_start >= half_turn ? best_start - half_turn : best_start + half_turn;
  auto sweep = [&](FringeSet id, std::int64_t start) {
    SetPlan set;
    set.set = id;
    set.period_deg = id == FringeSet::High ? th : tl;
    set.step_deg = step_deg;
    for (int k = 0; k < n; ++k)
      set.positions.push_back(start + k * step);
    return set;
  };
  plan.high = sweep(FringeSet::High, best_start);
  plan.low = sweep(FringeSet::Low, start2);
  RingLayout layout;
  layout.start_deg = static_cast<double>(best_start) / spd;
  layout.sweep2_start_deg = static_cast<double>(start2) / spd;
  layout.step_steps = step;
  layout.step_deg = step_deg;
  layout.frames = n;
  layout.noise_gain_high = gain_high;
  layout.noise_gain_low = gain_low;
  layout.cameras = best.cameras;
  for (const auto& c : layout.cameras)
    if (c.first_sweep_set == FringeSet::Low) plan.swapped.insert(c.camera);
  plan.ring = std::move(layout);
}

}  // namespace

double phaseNoiseGain(const std::vector<double>& shifts_rad) {
  const auto n = static_cast<double>(shifts_rad.size());
  if (shifts_rad.size() < 3) return std::numeric_limits<double>::infinity();
  cv::Matx33d m = cv::Matx33d::zeros();
  for (const double d : shifts_rad) {
    const cv::Vec3d r(1.0, std::cos(d), std::sin(d));
    m += r * r.t();
  }
  // Relative to the trace: the matrix of N equal shifts is diag(N, N/2, N/2).
  const double det = cv::determinant(m);
  if (!(std::abs(det) > 1e-9 * n * n * n)) return std::numeric_limits<double>::infinity();
  const cv::Matx33d inv = m.inv(cv::DECOMP_LU);
  // var φ averaged over φ is σ²(inv_CC + inv_SS)/(2B²); ideal: σ²·2/(N B²).
  const double ratio = (inv(1, 1) + inv(2, 2)) / 2.0 / (2.0 / n);
  return ratio > 0 ? std::sqrt(ratio) : std::numeric_limits<double>::infinity();
}

ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile) {
  return scanOptionsFrom(profile, readScanProfile(profile));
}

ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile, const ScanProfile& scan) {
  ScanOptions o;
  o.frames_high = scan.frames_high;
  o.frames_low = scan.frames_low;
  o.period_high_deg = scan.period_high_deg;
  o.period_low_deg = scan.period_low_deg;
  o.high_start_deg = scan.high_start_deg;
  o.low_start_deg = scan.low_start_deg;
  o.mode = scan.mode;
  o.settle_ms = settleMs(profile, scan);
  o.frame_timeout_ms = scan.frame_timeout_ms;
  o.verify_steps = scan.verify_steps;
  o.plan = scan.plan;
  o.step_deg = scan.step_deg;
  o.high_half_start_deg = scan.high_half_start_deg;
  if (o.plan == PlanKind::Ring) {
    o.cameras.clear();
    for (const auto& camera : profile.cameras) {
      o.cameras.push_back(camera.name);
      if (camera.azimuth_deg) {
        o.azimuths.push_back({camera.name, (*camera.azimuth_deg)[0], (*camera.azimuth_deg)[1]});
      }
    }
  }
  o.exposure_us = 0;
  o.frame_rate_hz = 1e9;
  for (const auto& camera : profile.cameras) {
    o.exposure_us = std::max(o.exposure_us, camera.config.exposure_us);
    o.trigger_pulse_us = std::max(o.trigger_pulse_us, camera.trigger_pulse_us);
    if (camera.frame_rate_hz > 0) o.frame_rate_hz = std::min(o.frame_rate_hz, camera.frame_rate_hz);
  }
  if (o.frame_rate_hz >= 1e9) o.frame_rate_hz = 30;
  return o;
}

ScanPlan cameraSetsPlan(const ScanPlan& ring, std::string_view camera) {
  if (!ring.ring) throw std::invalid_argument("cameraSetsPlan: not a ring plan");
  const auto& cams = ring.ring->cameras;
  if (std::none_of(cams.begin(), cams.end(),
                   [&](const RingCamera& c) { return c.camera == camera; })) {
    throw std::invalid_argument("cameraSetsPlan: the ring plan has no camera '" +
                                std::string(camera) + "'");
  }
  ScanPlan out;
  out.high = ring.motionSetOf(camera, FringeSet::High);
  out.high.set = FringeSet::High;
  out.high.period_deg = ring.period_high_deg;
  out.low = ring.motionSetOf(camera, FringeSet::Low);
  out.low.set = FringeSet::Low;
  out.low.period_deg = ring.period_low_deg;
  out.steps_per_deg = ring.steps_per_deg;
  out.period_high_deg = ring.period_high_deg;
  out.period_low_deg = ring.period_low_deg;
  return out;
}

std::vector<double> ScanPlan::anglesDeg(FringeSet id) const {
  std::vector<double> out;
  for (const auto p : set(id).positions)
    out.push_back(static_cast<double>(p) / steps_per_deg);
  return out;
}

FringeSet ScanPlan::setOf(std::string_view camera, FringeSet motion_set) const {
  if (!swapped.contains(camera)) return motion_set;
  return motion_set == FringeSet::High ? FringeSet::Low : FringeSet::High;
}

const SetPlan& ScanPlan::motionSetOf(std::string_view camera, FringeSet set) const {
  // setOf is its own inverse: a swap or the identity.
  return this->set(setOf(camera, set));
}

std::vector<double> ScanPlan::anglesDeg(std::string_view camera, FringeSet id) const {
  std::vector<double> out;
  for (const auto p : motionSetOf(camera, id).positions)
    out.push_back(static_cast<double>(p) / steps_per_deg);
  return out;
}

ScanPlan planScan(const ScanOptions& options, const drivers::StageConfig& stage) {
  ScanPlan plan;
  plan.steps_per_deg = stage.stepsPerDeg();
  if (!(plan.steps_per_deg > 0)) throw std::invalid_argument("scan: the stage has no steps");
  plan.period_high_deg = options.period_high_deg;
  plan.period_low_deg = options.period_low_deg;
  if (options.plan == PlanKind::Ring) {
    planRing(options, plan);
    return plan;
  }
  plan.high = planSet(FringeSet::High, options.period_high_deg, options.frames_high,
                      options.high_start_deg, plan.steps_per_deg);
  plan.low = planSet(FringeSet::Low, options.period_low_deg, options.frames_low,
                     options.low_start_deg, plan.steps_per_deg);
  return plan;
}

}  // namespace cylscan::firmware
