// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/sim_gpio.hpp"

#include <string>

#include "drivers/sim/head_core.hpp"

namespace cylscan::sim {

namespace {

using drivers::GpioError;
using drivers::LineSpec;

std::string describe(const LineSpec& spec) {
  std::string d = "line";
  if (!spec.role.empty()) d += " for role '" + spec.role + "'";
  if (!spec.name.empty()) {
    d += " named '" + spec.name + "'";
  } else {
    d += " at " + spec.chip + ":" + std::to_string(spec.offset);
  }
  return d;
}

// Claims a line: the role it names on the virtual head, or a GpioError.
LineRole claim(HeadCore& core, const LineSpec& spec, bool output) {
  if (spec.name.empty()) {
    throw GpioError("sim gpio: " + describe(spec) +
                    ": the virtual head's lines are found by name, not chip/offset");
  }
  const std::optional<LineRole> role = core.roleOf(spec.name);
  if (!role) {
    throw GpioError("sim gpio: " + describe(spec) + ": no such line (the virtual head has " +
                    core.config.lines.step.name + ", " + core.config.lines.dir.name + ", " +
                    core.config.lines.enable.name + ", " + core.config.lines.trigger.name + ", " +
                    core.config.lines.light.name + ", " + core.config.lines.home.name + ", " +
                    core.config.lines.fault.name + ")");
  }
  if (isInput(*role) == output) {
    throw GpioError("sim gpio: " + describe(spec) + ": is an " +
                    (isInput(*role) ? "input" : "output") + " of the virtual head");
  }
  const auto r = static_cast<std::size_t>(*role);
  if (core.requested[r])
    throw GpioError("sim gpio: " + describe(spec) + ": busy (already requested)");
  core.requested[r] = true;
  return *role;
}

class SimOutputLine final : public drivers::OutputLine {
 public:
  SimOutputLine(HeadCore& core, LineRole role, bool active_low)
      : core_(core), role_(role), invert_(active_low != core.line(role).active_low) {}
  ~SimOutputLine() override { core_.requested[static_cast<std::size_t>(role_)] = false; }
  SimOutputLine(const SimOutputLine&) = delete;
  SimOutputLine& operator=(const SimOutputLine&) = delete;

  // Physical level = active XOR the request's active_low; the device reads it
  // through its own polarity.
  void set(bool active) override { core_.drive(role_, active != invert_); }

 private:
  HeadCore& core_;
  LineRole role_;
  bool invert_;
};

class SimInputLine final : public drivers::InputLine {
 public:
  SimInputLine(HeadCore& core, LineRole role, bool active_low)
      : core_(core), role_(role), invert_(active_low != core.line(role).active_low) {
    queue().clear();  // edges before the request are not reported
  }
  ~SimInputLine() override { core_.requested[static_cast<std::size_t>(role_)] = false; }
  SimInputLine(const SimInputLine&) = delete;
  SimInputLine& operator=(const SimInputLine&) = delete;

  bool get() override {
    const bool device = role_ == LineRole::Home ? core_.stage.homeActive() : core_.stage.fault();
    return device != invert_;
  }

  std::optional<drivers::LineEvent> waitEdge(drivers::Nanoseconds timeout) override {
    const drivers::Nanoseconds deadline =
        core_.clock.now() + std::max(timeout, drivers::Nanoseconds{0});
    for (;;) {
      const std::uint64_t epoch = core_.clock.eventEpoch();  // before looking
      if (auto e = queue().front()) {
        queue().pop();
        const bool active = e->active != invert_;
        return drivers::LineEvent{active ? drivers::Edge::Rising : drivers::Edge::Falling, e->time};
      }
      if (core_.clock.now() >= deadline) return std::nullopt;
      // Nothing moves while we wait unless another thread drives the stage:
      // wait for an event or the deadline (alone in virtual time: at once).
      core_.clock.waitForEvent(epoch, deadline);
    }
  }

 private:
  struct Queue {
    SimInputLine& line;
    std::optional<StageModel::Edge> front() {
      return line.role_ == LineRole::Home ? line.core_.stage.homeEdges().front()
                                          : line.core_.stage.faultEdges().front();
    }
    void pop() {
      if (line.role_ == LineRole::Home) {
        line.core_.stage.homeEdges().pop();
      } else {
        line.core_.stage.faultEdges().pop();
      }
    }
    void clear() {
      if (line.role_ == LineRole::Home) {
        line.core_.stage.homeEdges().clear();
      } else {
        line.core_.stage.faultEdges().clear();
      }
    }
  };
  Queue queue() { return Queue{*this}; }

  HeadCore& core_;
  LineRole role_;
  bool invert_;
};

}  // namespace

std::unique_ptr<drivers::OutputLine> SimGpio::requestOutput(const LineSpec& spec,
                                                            bool initial_active) {
  const LineRole role = claim(core_, spec, true);
  auto line = std::make_unique<SimOutputLine>(core_, role, spec.active_low);
  line->set(initial_active);
  return line;
}

std::unique_ptr<drivers::InputLine> SimGpio::requestInput(const LineSpec& spec) {
  const LineRole role = claim(core_, spec, false);
  return std::make_unique<SimInputLine>(core_, role, spec.active_low);
}

}  // namespace cylscan::sim
