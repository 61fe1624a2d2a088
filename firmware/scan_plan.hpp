// SPDX-License-Identifier: Apache-2.0
// The scan plan: where the stage is for every
// frame of both fringe sets, in exact step counts, before anything moves.
//
// The high set's frame k is exposed at high_start + round(k·θh/N) steps, the
// low set's at low_start + round(k·θl/N); the executed angle of a frame is its
// step position over the stage's steps per degree, which is what the capture
// bundle records. Stop-and-go moves to each position and settles; continuous
// mode sweeps each set at constant speed and triggers at those positions.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/board_profile.hpp"
#include "drivers/stage_config.hpp"
#include "firmware/scan_profile.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

// A camera's working volume in projector azimuth (degrees about the projector
// axis; at stage angle ρ the wall angle lighting azimuth a is β = a − ρ).
struct CameraAzimuth {
  std::string camera;
  double lo_deg = 0;
  double hi_deg = 0;
};

struct ScanOptions {
  int frames_high = 25;
  int frames_low = 25;
  double period_high_deg = 5.0;  // θh: the projector's slot interval of the high set
  double period_low_deg = 5.625;
  double high_start_deg = 0;
  double low_start_deg = 0;
  ScanMode mode = ScanMode::StopAndGo;
  double settle_ms = 100;
  double frame_timeout_ms = 1000;
  // Continuous mode: the constant speed; 0 = one frame step per frame period
  // of the slowest camera (`frame_rate_hz`), or the stage's top speed when
  // that is lower.
  double sweep_speed_deg_s = 0;
  double frame_rate_hz = 30;
  double exposure_us = 10000;  // the longest exposure of the cameras used
  double trigger_pulse_us = 10;
  // Check the step count at a home edge: passed on the way, or sought after
  // the scan when it passed none. Lost steps fail the scan.
  bool verify_steps = true;
  // The motion thread: SCHED_FIFO priority and mlockall (both when allowed).
  int realtime_priority = 80;
  bool lock_memory = true;
  std::vector<std::string> cameras{"main"};
  // The ring plan of a 360° head (PlanKind::Ring): both sweeps step by
  // `step_deg` (0: the planner chooses it), the high slots cover wall angles
  // [h0, h0 + 180), and every camera of `cameras` has its azimuths here.
  PlanKind plan = PlanKind::Sets;
  double step_deg = 0;
  double high_half_start_deg = 0;
  std::vector<CameraAzimuth> azimuths;
  // The least distance (degrees of wall angle) a camera's working volume keeps
  // from a half boundary during its sweeps and from an equivalent-period wrap
  // at its set's first frame: the slots' blur and the phase noise need room.
  double ring_margin_deg = 1.0;
};

// The defaults of a board: its [scan] (read by readScanProfile, whose
// ConfigError it throws), its [stage] and its cameras.
ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile);
// The same from a [scan] already read.
ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile, const ScanProfile& scan);

struct SetPlan {
  // The set this motion set is (sets plan), or the set it is for main (ring plan).
  FringeSet set = FringeSet::High;
  double period_deg = 0;                // that set's period θ
  double step_deg = 0;                  // the nominal frame step: θ/N (sets), Δ (ring)
  std::vector<std::int64_t> positions;  // stage steps of each frame (absolute, from home)
};

// What the ring planner chose for one camera.
struct RingCamera {
  std::string camera;
  FringeSet first_sweep_set = FringeSet::High;  // the set sweep 1 gives it
  double window_margin_deg = 0;  // to the nearest equivalent-period wrap, at its sets' first frames
  double half_margin_deg = 0;    // to the nearest half boundary, over its sweeps
};

// The ring plan of a 360° head: sweep 1 from `start_deg`, sweep 2 from 180° away,
// both `frames` frames at `step_steps` motor steps. Cameras facing the high
// half in sweep 1 take it as their high set and sweep 2 as their low set; the
// others the other way round. So each set of a camera is stepped by the same
// Δ, which is 2πΔ/θh per frame for its high set and 2πΔ/θl for its low set:
// the executed-shift least squares handles both; `noise_gain_*` is the phase
// noise of that set's shifts over that of N equal shifts over one period
// (1 = the ideal N-step; the planner picks Δ to make the worse of the two small).
struct RingLayout {
  double start_deg = 0;
  double sweep2_start_deg = 0;
  std::int64_t step_steps = 0;
  double step_deg = 0;
  int frames = 0;
  double noise_gain_high = 0;
  double noise_gain_low = 0;
  std::vector<RingCamera> cameras;
};

struct ScanPlan {
  // The two motion sets, in the order the stage runs them. Sets plan: the
  // high and the low set. Ring plan: sweep 1 (main's high set) and sweep 2
  // (main's low set).
  SetPlan high;
  SetPlan low;
  double steps_per_deg = 0;
  double period_high_deg = 5.0;  // θh
  double period_low_deg = 5.625;
  std::optional<RingLayout> ring;
  // Ring: the cameras whose sweep 1 is their low set. Empty for a sets plan.
  std::set<std::string, std::less<>> swapped;

  const SetPlan& set(FringeSet id) const { return id == FringeSet::High ? high : low; }
  // The set that a camera's frames of motion set `motion_set` belong to.
  FringeSet setOf(std::string_view camera, FringeSet motion_set) const;
  // The motion set that holds a camera's set `set` (the inverse of setOf).
  const SetPlan& motionSetOf(std::string_view camera, FringeSet set) const;
  // The executed angles of a set (steps / steps per degree): main's, and a camera's own.
  std::vector<double> anglesDeg(FringeSet id) const;
  std::vector<double> anglesDeg(std::string_view camera, FringeSet set) const;
  double periodDeg(FringeSet set) const {
    return set == FringeSet::High ? period_high_deg : period_low_deg;
  }
  int frames() const { return static_cast<int>(high.positions.size() + low.positions.size()); }
};

// The phase noise of a least-squares fit with these shifts (radians), as a
// multiple of the noise with the same number of equal shifts over one period
// (1 for N ≥ 3 equal steps of 2π/N). Infinite when the fit is singular.
double phaseNoiseGain(const std::vector<double>& shifts_rad);

// std::invalid_argument naming the option when the plan is impossible (N < 3,
// periods not positive, a frame step below one motor step). With a ring plan,
// also naming the camera when no start angle keeps every camera's working
// volume inside one equivalent period at its sets' first frames and off the
// half boundaries during its sweeps (or when a camera has no azimuths).
ScanPlan planScan(const ScanOptions& options, const drivers::StageConfig& stage);

// One camera's two sets of a ring plan as a plan of their own (high, then
// low, at the ring's positions for that camera): the calibration scans of a
// 360° head's camera, taken one direction at a time with a temporary aux
// camera beside it, must share the phase origin of that camera's ring sets.
// std::invalid_argument when `ring` is not a ring plan or has no such camera.
ScanPlan cameraSetsPlan(const ScanPlan& ring, std::string_view camera);

}  // namespace cylscan::firmware
