// SPDX-License-Identifier: Apache-2.0
#include "drivers/libcamera_logic.hpp"

#include <array>

namespace cylscan::drivers {

std::optional<MonoFormat> libcameraMonoFormat(std::string_view name) {
  static const std::array<MonoFormat, 6> kFormats{{
      {"R8", MonoPacking::U8, 8},
      {"R10", MonoPacking::U16LE, 10},
      {"R12", MonoPacking::U16LE, 12},
      {"R16", MonoPacking::U16LE, 16},
      {"R10_CSI2P", MonoPacking::Csi2P10, 10},
      {"R12_CSI2P", MonoPacking::Csi2P12, 12},
  }};
  for (const MonoFormat& f : kFormats) {
    if (f.name == name) return f;
  }
  return std::nullopt;
}

ClampedValue clampValue(double requested, std::optional<double> minimum,
                        std::optional<double> maximum) {
  double v = requested;
  if (minimum && v < *minimum) v = *minimum;
  if (maximum && v > *maximum) v = *maximum;
  return {v, v != requested};
}

ControlRange libcameraControl(double value, std::optional<double> minimum,
                              std::optional<double> maximum) {
  ControlRange r{value, minimum.value_or(value), maximum.value_or(value)};
  if (r.max < r.min) r.min = r.max = value;
  return r;
}

}  // namespace cylscan::drivers
