// SPDX-License-Identifier: Apache-2.0
// The rotation stage of the virtual head: a geared stepper that moves one
// microstep per step pulse while enabled, loses steps when driven faster or
// harder than its torque allows, rings after motion and has a home switch.
#pragma once

#include <chrono>
#include <cstdint>
#include <random>

#include "drivers/gpio.hpp"
#include "drivers/sim/event_ring.hpp"

namespace cylscan::sim {

struct StageParams {
  int full_steps_per_rev = 200;     // motor
  int microsteps = 10;              // driver setting
  double gear_ratio = 45.0;         // worm gear: 200 × 10 × 45 = 90000 steps/rev = 0.004°/step
  double max_speed_deg_s = 30.0;    // pull-out: faster step trains are not followed
  double max_accel_deg_s2 = 120.0;  // torque limit on speed changes
  double start_speed_deg_s = 4.0;   // start/stop rate: steps this slow are always followed
  double home_deg = 0.0;            // home switch centre
  double home_window_deg = 0.2;     // width of the angle range where it is active
  double settle_amplitude_deg = 0.01;  // ringing after a stop from full speed
  double settle_tau_ms = 30.0;         // decay time constant of the ringing
  double settle_freq_hz = 40.0;
  double initial_deg = 0.0;  // where the stage is at power-up
  // Play in the gear train: after a reversal the motor turns this far before
  // the stage follows. The home switch and the projector sit on the stage.
  double backlash_deg = 0.0;
  // The home switch trips a little early or late on each approach: its edge
  // moves by a Gaussian of this σ, drawn anew whenever the switch releases
  // (from home_seed: the same sequence on every run).
  double home_repeatability_deg = 0.0;
  std::uint64_t home_seed = 1;

  bool operator==(const StageParams&) const = default;
  double stepsPerDeg() const { return full_steps_per_rev * microsteps * gear_ratio / 360.0; }
};

// Throws std::invalid_argument naming the parameter when a value is impossible.
void validate(const StageParams& params);

struct StageCounters {
  std::uint64_t pulses = 0;    // step pulses received while enabled
  std::uint64_t ignored = 0;   // step pulses received while disabled
  std::uint64_t lost = 0;      // pulses received but not executed
  std::uint64_t forward = 0;   // executed steps in the + direction
  std::uint64_t backward = 0;  // executed steps in the − direction
};

class StageModel {
 public:
  using Nanoseconds = std::chrono::nanoseconds;
  explicit StageModel(const StageParams& params);

  const StageParams& params() const { return params_; }

  // Inputs, driven by the GPIO lines (real-time safe: no allocation, no lock).
  void setEnabled(bool enabled, Nanoseconds t);
  void setDirection(bool forward);
  void stepPulse(Nanoseconds t);  // a rising edge on the step input

  // Fault injection and the fault output.
  void loseNextSteps(std::uint64_t count) { inject_loss_ += count; }
  // The `count` pulses after the first `after` ones are lost.
  void loseStepsAfter(std::uint64_t after, std::uint64_t count) {
    scheduled_loss_after_ = after;
    scheduled_loss_ = count;
  }
  // A broken home switch: never active.
  void breakHomeSwitch() {
    home_switch_broken_ = true;
    home_ = false;
  }
  void setFault(bool fault, Nanoseconds t);
  bool fault() const { return fault_; }

  std::int64_t position() const { return position_; }  // executed microsteps from zero
  // The stage's own angle: the motor's, less the backlash taken up.
  double angleDeg() const { return output_ / steps_per_deg_; }
  // The angle at a past time, with the ringing after the last step.
  double angleAt(Nanoseconds t) const;
  bool homeActive() const { return home_; }
  bool enabled() const { return enabled_; }
  const StageCounters& counters() const { return counters_; }
  // How many home and fault edges were queued so far (to notice new ones).
  std::uint64_t edgeCount() const { return edge_count_; }

  struct Edge {
    bool active = false;
    Nanoseconds time{0};
  };
  // Edges of the home switch and of the fault output, in virtual time.
  SpscQueue<Edge, 4096>& homeEdges() { return home_edges_; }
  SpscQueue<Edge, 256>& faultEdges() { return fault_edges_; }

 private:
  struct Sample {
    Nanoseconds time{0};
    double position = 0;     // the stage's, in microsteps (backlash taken up)
    double speed_deg_s = 0;  // at this step (0 for a state change without motion)
  };
  bool followed(Nanoseconds t, int direction);
  bool homeAt(double position) const;
  void drawHomeOffset();

  StageParams params_;
  double steps_per_deg_;
  std::int64_t position_;  // the motor's, in microsteps
  double output_ = 0;      // the stage's: within half the backlash of the motor
  double half_backlash_ = 0;
  double home_offset_deg_ = 0;  // this approach's shift of the switch edge
  std::mt19937_64 home_rng_;
  bool enabled_ = false;
  bool forward_ = true;
  bool home_ = false;
  bool fault_ = false;
  bool stalled_ = false;
  std::uint64_t inject_loss_ = 0;
  std::uint64_t scheduled_loss_after_ = 0;
  std::uint64_t scheduled_loss_ = 0;
  bool home_switch_broken_ = false;
  std::uint64_t edge_count_ = 0;
  // Previous pulse (executed or not) for the speed/acceleration rule.
  bool have_previous_ = false;
  Nanoseconds previous_time_{0};
  double previous_speed_ = 0;  // signed steps/s
  StageCounters counters_;
  HistoryRing<Sample, 65536> history_;
  SpscQueue<Edge, 4096> home_edges_;
  SpscQueue<Edge, 256> fault_edges_;
};

}  // namespace cylscan::sim
