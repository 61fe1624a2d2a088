// SPDX-License-Identifier: Apache-2.0
// GPIO lines through the kernel's GPIO character device with libgpiod v2's
// C++ bindings. Lines are found by name across all chips under a device
// directory, or by chip (path, device name or label) and offset.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "drivers/gpio.hpp"
#include "drivers/gpio_lookup.hpp"

namespace cylscan::drivers {

class GpiodBackend final : public GpioBackend {
 public:
  // Reads the chips under `device_dir` (every gpiochip device) on first use.
  // `consumer` is the name the kernel shows for the requested lines.
  explicit GpiodBackend(std::filesystem::path device_dir = "/dev",
                        std::string consumer = "cylscan");

  // Outputs: step, dir, enable, camera triggers, light. set() does not allocate.
  std::unique_ptr<OutputLine> requestOutput(const LineSpec& spec, bool initial_active) override;
  // Inputs with both edges detected and CLOCK_MONOTONIC kernel timestamps.
  std::unique_ptr<InputLine> requestInput(const LineSpec& spec) override;

  // The chips as read (for diagnostics); throws GpioError when none can be read.
  const std::vector<ChipLines>& chips();

 private:
  LineLocation locate(const LineSpec& spec);

  std::filesystem::path device_dir_;
  std::string consumer_;
  std::vector<ChipLines> chips_;
  bool scanned_ = false;
};

}  // namespace cylscan::drivers
