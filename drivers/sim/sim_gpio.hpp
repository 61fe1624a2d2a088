// SPDX-License-Identifier: Apache-2.0
// The GPIO backend of the virtual head: lines found by name act on its stage,
// cameras and light source; inputs report the home switch and the stage fault.
#pragma once

#include <memory>

#include "drivers/gpio.hpp"

namespace cylscan::sim {

struct HeadCore;

class SimGpio final : public drivers::GpioBackend {
 public:
  explicit SimGpio(HeadCore& core) : core_(core) {}
  std::unique_ptr<drivers::OutputLine> requestOutput(const drivers::LineSpec& spec,
                                                     bool initial_active) override;
  std::unique_ptr<drivers::InputLine> requestInput(const drivers::LineSpec& spec) override;

 private:
  HeadCore& core_;
};

}  // namespace cylscan::sim
