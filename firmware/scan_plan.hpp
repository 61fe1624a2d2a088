// The scan plan (issue "Real-time acquisition"): where the stage is for every
// frame of both fringe sets, in exact step counts, before anything moves.
//
// The high set's frame k is exposed at high_start + round(k·θh/N) steps, the
// low set's at low_start + round(k·θl/N); the executed angle of a frame is its
// step position over the stage's steps per degree, which is what the capture
// bundle records. Stop-and-go moves to each position and settles; continuous
// mode sweeps each set at constant speed and triggers at those positions.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "drivers/board_profile.hpp"
#include "drivers/stage_config.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

struct ScanOptions {
  int frames_high = 25;
  int frames_low = 25;
  double period_high_deg = 5.0;  // θh: the projector's slot interval of the high set
  double period_low_deg = 5.625;
  double high_start_deg = 0;
  double low_start_deg = 0;
  drivers::ScanMode mode = drivers::ScanMode::StopAndGo;
  double settle_ms = 100;
  double frame_timeout_ms = 1000;
  // Continuous mode: the constant speed; 0 = one frame step per frame period
  // of the slowest camera (`frame_rate_hz`).
  double sweep_speed_deg_s = 0;
  double frame_rate_hz = 30;
  double exposure_us = 10000;  // the longest exposure of the cameras used
  double trigger_pulse_us = 10;
  bool verify_steps = true;  // re-seek home after the scan: lost steps fail it
  // The motion thread: SCHED_FIFO priority and mlockall (both when allowed).
  int realtime_priority = 80;
  bool lock_memory = true;
  std::vector<std::string> cameras{"main"};
};

// The defaults of a board profile ([scan], [stage] and the cameras).
ScanOptions scanOptionsFrom(const drivers::BoardProfile& profile);

struct SetPlan {
  formats::FringeSetId set = formats::FringeSetId::High;
  double period_deg = 0;
  std::vector<std::int64_t> positions;  // stage steps of each frame (absolute, from home)
};

struct ScanPlan {
  SetPlan high;
  SetPlan low;
  double steps_per_deg = 0;
  const SetPlan& set(formats::FringeSetId id) const {
    return id == formats::FringeSetId::High ? high : low;
  }
  // The executed angles of a set (steps / steps per degree).
  std::vector<double> anglesDeg(formats::FringeSetId id) const;
  int frames() const { return static_cast<int>(high.positions.size() + low.positions.size()); }
};

// std::invalid_argument naming the option when the plan is impossible (N < 3,
// periods not positive, a frame step below one motor step).
ScanPlan planScan(const ScanOptions& options, const drivers::StageConfig& stage);

}  // namespace cylscan::firmware
