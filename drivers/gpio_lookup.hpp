// SPDX-License-Identifier: Apache-2.0
// Finding a GPIO line from a LineSpec in the tables of the system's chips:
// pure logic, without devices, shared by the gpiod backend and its tests.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/gpio.hpp"

namespace cylscan::drivers {

// What one GPIO chip offers: its device path, its label and its line names by offset.
struct ChipLines {
  std::string path;                // "/dev/gpiochip0"
  std::string label;               // "pinctrl-rp1" (may be empty)
  std::vector<std::string> names;  // names[offset]; empty for unnamed lines
};

// Where a line is: the chip's path and the line's offset on it.
struct LineLocation {
  std::string chip;  // device path
  unsigned int offset = 0;
  bool operator==(const LineLocation&) const = default;
};

// "step line 'GPIO17'" or "home line gpiochip0:17": for messages.
std::string describeLine(const LineSpec& spec);

// Whether `chip` (a spec's "gpiochip0", "/dev/gpiochip0" or chip label) names `lines`.
bool chipMatches(std::string_view chip, const ChipLines& lines);

// Resolves a spec against the chips. By name: the line of that name on exactly
// one chip (a name on two chips, or twice on one, is ambiguous). By chip and
// offset: the chip named by path, device name or label, and an offset inside
// it. Throws GpioError naming the line's role and name or chip/offset.
LineLocation resolveLine(const LineSpec& spec, const std::vector<ChipLines>& chips);

}  // namespace cylscan::drivers
