// SPDX-License-Identifier: Apache-2.0
#include "drivers/gpio_lookup.hpp"

#include <filesystem>
#include <optional>

namespace cylscan::drivers {

std::string describeLine(const LineSpec& spec) {
  std::string d = spec.role.empty() ? std::string("line") : spec.role + " line";
  if (!spec.name.empty()) return d + " '" + spec.name + "'";
  return d + " " + (spec.chip.empty() ? std::string("(no chip)") : spec.chip) + ":" +
         std::to_string(spec.offset);
}

bool chipMatches(std::string_view chip, const ChipLines& lines) {
  if (chip.empty()) return false;
  if (chip == lines.path || (!lines.label.empty() && chip == lines.label)) return true;
  return std::filesystem::path(lines.path).filename() == chip;
}

namespace {

std::string chipList(const std::vector<ChipLines>& chips) {
  std::string out;
  for (const ChipLines& c : chips) {
    if (!out.empty()) out += ", ";
    out += c.path;
    if (!c.label.empty()) out += " (" + c.label + ")";
  }
  return out.empty() ? std::string("none") : out;
}

LineLocation byName(const LineSpec& spec, const std::vector<ChipLines>& chips) {
  std::optional<LineLocation> found;
  for (const ChipLines& c : chips) {
    for (std::size_t i = 0; i < c.names.size(); ++i) {
      if (c.names[i] != spec.name) continue;
      const LineLocation here{c.path, static_cast<unsigned int>(i)};
      if (found) {
        throw GpioError("gpio: " + describeLine(spec) + " is ambiguous: found at " + found->chip +
                        ":" + std::to_string(found->offset) + " and at " + here.chip + ":" +
                        std::to_string(here.offset) + "; give chip and offset instead");
      }
      found = here;
    }
  }
  if (!found) {
    throw GpioError("gpio: " + describeLine(spec) +
                    " not found on any GPIO chip (chips: " + chipList(chips) + ")");
  }
  return *found;
}

LineLocation byOffset(const LineSpec& spec, const std::vector<ChipLines>& chips) {
  const ChipLines* match = nullptr;
  for (const ChipLines& c : chips) {
    if (!chipMatches(spec.chip, c)) continue;
    if (match != nullptr) {
      throw GpioError("gpio: " + describeLine(spec) + ": chip '" + spec.chip +
                      "' is ambiguous: it names " + match->path + " and " + c.path);
    }
    match = &c;
  }
  if (match == nullptr) {
    throw GpioError("gpio: " + describeLine(spec) + ": no GPIO chip '" + spec.chip +
                    "' (chips: " + chipList(chips) + ")");
  }
  if (spec.offset < 0 || static_cast<std::size_t>(spec.offset) >= match->names.size()) {
    throw GpioError("gpio: " + describeLine(spec) + ": offset out of range (" + match->path +
                    " has " + std::to_string(match->names.size()) + " lines)");
  }
  return {match->path, static_cast<unsigned int>(spec.offset)};
}

}  // namespace

LineLocation resolveLine(const LineSpec& spec, const std::vector<ChipLines>& chips) {
  const bool by_name = !spec.name.empty();
  const bool by_offset = !spec.chip.empty() || spec.offset >= 0;
  if (by_name == by_offset) {
    throw GpioError("gpio: " + describeLine(spec) +
                    ": give either a line name or a chip and an offset");
  }
  return by_name ? byName(spec, chips) : byOffset(spec, chips);
}

}  // namespace cylscan::drivers
