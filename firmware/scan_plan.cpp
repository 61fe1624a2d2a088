#include "firmware/scan_plan.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cylscan::firmware {
namespace {

SetPlan planSet(formats::FringeSetId id, double period_deg, int frames, double start_deg,
                double steps_per_deg) {
  const std::string name(formats::toString(id));
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
  const auto start = std::llround(start_deg * steps_per_deg);
  for (int k = 0; k < frames; ++k)
    plan.positions.push_back(start + std::llround(k * period_deg / frames * steps_per_deg));
  return plan;
}

}  // namespace

ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile) {
  ScanOptions o;
  o.frames_high = profile.scan.frames_high;
  o.frames_low = profile.scan.frames_low;
  o.period_high_deg = profile.scan.period_high_deg;
  o.period_low_deg = profile.scan.period_low_deg;
  o.high_start_deg = profile.scan.high_start_deg;
  o.low_start_deg = profile.scan.low_start_deg;
  o.mode = profile.scan.mode;
  o.settle_ms = profile.settleMs();
  o.frame_timeout_ms = profile.scan.frame_timeout_ms;
  o.verify_steps = profile.scan.verify_steps;
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

std::vector<double> ScanPlan::anglesDeg(formats::FringeSetId id) const {
  std::vector<double> out;
  for (const auto p : set(id).positions)
    out.push_back(static_cast<double>(p) / steps_per_deg);
  return out;
}

ScanPlan planScan(const ScanOptions& options, const drivers::StageConfig& stage) {
  ScanPlan plan;
  plan.steps_per_deg = stage.stepsPerDeg();
  if (!(plan.steps_per_deg > 0)) throw std::invalid_argument("scan: the stage has no steps");
  plan.high = planSet(formats::FringeSetId::High, options.period_high_deg, options.frames_high,
                      options.high_start_deg, plan.steps_per_deg);
  plan.low = planSet(formats::FringeSetId::Low, options.period_low_deg, options.frames_low,
                     options.low_start_deg, plan.steps_per_deg);
  return plan;
}

}  // namespace cylscan::firmware
