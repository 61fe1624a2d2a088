// SPDX-License-Identifier: Apache-2.0
// A board's [scan] table: how the firmware scans with this head (the mode,
// the plan and their defaults). The board profile (drivers/board_profile.hpp)
// describes the hardware and keeps [scan] unread; the firmware owns its meaning.
// Format: board/README.md.
#pragma once

#include <optional>
#include <string_view>

#include "drivers/board_profile.hpp"

namespace cylscan::firmware {

enum class ScanMode { StopAndGo, Continuous };
std::string_view toString(ScanMode mode);  // "stop" | "continuous"

// How the stage angles of the two sets are planned. Sets: each set at its own
// start in steps of θ/N (one camera, or cameras that face the same half).
// Ring: two sweeps 180° apart in one common step for every camera of a 360°
// head; each camera takes the high or the low set from a sweep according to
// the half of the cylinder it faces (scan_plan.hpp).
enum class PlanKind { Sets, Ring };
std::string_view toString(PlanKind plan);  // "sets" | "ring"

struct ScanProfile {
  int frames_high = 25;
  int frames_low = 25;
  // The sets plan's stage angles of each set's first frame. They depend on
  // where the home switch sits against the cylinder's two slot halves, so
  // every board states them ([scan] high_start_deg, low_start_deg); there is
  // no default.
  double high_start_deg = 0;
  double low_start_deg = 0;
  ScanMode mode = ScanMode::StopAndGo;
  double frame_timeout_ms = 1000.0;
  std::optional<double> settle_ms;  // overrides [stage] settle_ms
  bool save_bundle = true;
  bool verify_steps = true;  // lost steps fail the scan: a home edge passed, else a re-seek
  // The projector's slot intervals: θh (high set) and θl (low set).
  double period_high_deg = 5.0;
  double period_low_deg = 5.625;
  PlanKind plan = PlanKind::Sets;
  // Ring: the common frame step (0: the planner chooses it) and the wall angle
  // where the high slots' half begins (h0: the high slots cover [h0, h0 + 180)).
  double step_deg = 0.0;
  double high_half_start_deg = 0.0;
};

// Reads the profile's [scan] table. Every fault throws drivers::ConfigError
// naming the board file, the line and the key; unknown keys are faults. The
// ring plan needs every camera's azimuth_deg.
ScanProfile readScanProfile(const drivers::BoardProfile& profile);

// The settle time of a stop-and-go frame: [scan] settle_ms, else the stage's.
double settleMs(const drivers::BoardProfile& board, const ScanProfile& scan);

}  // namespace cylscan::firmware
