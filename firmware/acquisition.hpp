// SPDX-License-Identifier: Apache-2.0
// The acquisition loop: the scan plan executed on the board through the
// driver interfaces, whatever the backends are (the virtual head or GPIO +
// V4L2/libcamera). Two threads:
//   - the motion thread (drivers::RealtimeThread: SCHED_FIFO and locked memory
//     when allowed) homes the stage when needed, moves and settles (or sweeps
//     at constant speed in continuous mode), and fires the trigger;
//   - the calling thread waits for each camera's frame, checks its sequence
//     and timestamp, and hands it to the FrameSink (the streaming fold). A
//     camera that streams continuously (drivers::FrameStream) gives the first
//     frame stamped its image latency after the trigger; the older ones are
//     passed over and its sequence gaps are not errors.
// They meet through atomics, and every wait is on the board's clock, so the
// virtual head's discrete-event clock runs the same code as real time.
//
// Frame k of motion set S (the plan's `high` then `low`) goes to camera c as
// its set plan.setOf(c, S): the same set for a sets plan; with a ring plan,
// the cameras facing the low half in sweep 1 get it as their low set.
//
// Faults: a camera timeout is retried once (stop-and-go triggers the frame
// again; continuous mode sweeps the set again and each camera skips the frames
// it already has), then the scan fails; a frame the camera lost without a
// timeout (a jump of its sequence numbers, for a camera that delivers one
// frame per exposure) fails it; so do a home switch that
// never fires, the stage fault input and lost steps.
//
// The stage homes only when it is not homed (power-up, a fault, an abort).
// The set nearer to where it stands runs first, so successive scans
// alternate and each starts where the last ended; the travel between the
// sets takes the way past home when that costs little, and the home edge it
// passes checks the step count on the fly. Only a scan that passed no home
// edge seeks home afterwards to check it (verify_steps). The last set's
// steps are checked at the next pass, which fails that scan and homes again. Whatever happens, the
// stage is disabled and the light is off when run() returns.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "drivers/board.hpp"
#include "drivers/jitter_stats.hpp"
#include "drivers/rotation_stage.hpp"
#include "firmware/frame_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "firmware/trigger_fanout.hpp"

namespace cylscan::firmware {

class ScanError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ScanProgress {
  int frames_done = 0;
  int frames_total = 0;
  FringeSet set = FringeSet::High;
};

// Where a scan's time went, on the board's clock.
struct ScanTimeSplit {
  std::chrono::nanoseconds homing{0};      // homing (and enabling the stage)
  std::chrono::nanoseconds travel{0};      // to each set's start
  std::chrono::nanoseconds sets{0};        // the sets' moves, sweeps, triggers and frames
  std::chrono::nanoseconds settling{0};    // stop-and-go: waiting for the stage to settle
  std::chrono::nanoseconds step_check{0};  // seeking home again to check the step count
};

// The split in seconds, by part: homing, travel, sets, settling, step_check.
std::map<std::string, double> timeSplitSeconds(const ScanTimeSplit& split);

struct ScanReport {
  std::vector<double> high_deg, low_deg;  // executed angles of the frames
  bool homed = false;                     // this scan homed the stage
  // The last check of the step count: on the way past home, or a re-seek.
  std::optional<drivers::StepCheck> step_check;
  std::chrono::nanoseconds duration{0};  // on the board's clock
  ScanTimeSplit split;
  FringeSet first_set = FringeSet::High;  // the motion set the stage ran first
  // Each set's time from its first trigger to its last frame (high, low).
  std::array<std::chrono::nanoseconds, 2> set_duration{};
  int frames = 0;
  int retries = 0;
  bool realtime = false;  // the motion thread got SCHED_FIFO
  std::vector<std::string> warnings;
  drivers::JitterStats::Snapshot step_jitter, trigger_jitter;
  // Late wake-ups of the step executor that delayed the rest of a move
  // (re-ramps), and by how much in all (drivers/step_executor.hpp).
  std::int64_t step_reramps = 0;
  std::chrono::nanoseconds step_slip{0};
};

// The shortest scan the stage's motion limits allow for a plan in continuous
// mode, the stage already homed: both sweeps (run-up, range, run-out) and the
// shorter travel between them, none of it waiting for anything else.
std::chrono::nanoseconds shortestScan(const ScanOptions& options, const ScanPlan& plan,
                                      const drivers::StageConfig& stage);

// One exposure of each camera where the stage stands: a checkerboard pair, a
// snapshot. The light is set to `light` for it and off afterwards.
struct StillOptions {
  std::vector<std::string> cameras{"main"};
  bool light = false;
  double frame_timeout_ms = 1000;
  double trigger_pulse_us = 10;
};

// What the firmware last drove on the head's outputs (the stage driver's
// enable line, the light line) and the stage's state when it last stopped
// (homed, position), for the daemon's status. Read from any thread.
struct HeadOutputs {
  bool stage_enabled = false;
  bool light = false;
  bool homed = false;
  double position_deg = 0.0;  // as the stage counts it (from home when homed)
};

class Acquisition {
 public:
  // Requests the stage, light and trigger lines of the board's profile
  // (drivers::GpioError naming a line that cannot be had).
  explicit Acquisition(drivers::Board& board);
  ~Acquisition();
  Acquisition(const Acquisition&) = delete;
  Acquisition& operator=(const Acquisition&) = delete;

  // Runs one scan of `plan` with the cameras of `options`. ScanError with the
  // reason when it fails or is aborted; the sink's own exceptions pass through
  // (the scan stops first).
  ScanReport run(const ScanOptions& options, const ScanPlan& plan, FrameSink& sink,
                 const std::function<void(const ScanProgress&)>& progress = {});

  // One trigger and each camera's first frame exposed after it (a continuous
  // stream's: stamped its image latency after it), in the order of
  // `options.cameras`; the stage does not move. A camera timeout triggers
  // once more; ScanError on a second one or an abort.
  std::vector<cv::Mat> still(const StillOptions& options);

  // The order the next scan of `plan` runs its two motion sets in, from where
  // the stage stands (from home when it is not homed): the nearer one first.
  std::array<FringeSet, 2> nextSetOrder(const ScanOptions& options, const ScanPlan& plan) const;

  // From any thread: the running scan stops as soon as it can and fails.
  void abort() noexcept;

  const drivers::RotationStage& stage() const { return *stage_; }

  // From any thread: the outputs' levels as set (every set() is seen at
  // once); homed and position are updated when a scan ends.
  HeadOutputs outputs() const;

 private:
  void publishStage();
  void armSoftwareTriggers(const std::vector<std::string>& cameras);
  struct Route;
  struct Shared;
  void motion(const ScanOptions& options, const ScanPlan& plan, Shared& shared);
  void capture(const ScanOptions& options, const ScanPlan& plan, FrameSink& sink, Shared& shared,
               const std::function<void(const ScanProgress&)>& progress, ScanReport& report);

  drivers::Board& board_;
  // Declared before the lines that write them.
  std::atomic<bool> enable_level_{false};
  std::atomic<bool> light_level_{false};
  std::atomic<bool> homed_{false};
  std::atomic<double> position_deg_{0.0};
  std::unique_ptr<drivers::RotationStage> stage_;
  std::unique_ptr<drivers::OutputLine> light_;
  TriggerFanout trigger_;
  std::atomic<bool> abort_{false};
};

}  // namespace cylscan::firmware
