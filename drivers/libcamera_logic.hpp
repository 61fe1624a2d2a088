// SPDX-License-Identifier: Apache-2.0
// The parts of the libcamera backend that need no camera: which of
// libcamera's pixel formats are monochrome, clamping to control ranges and
// reporting them.
#pragma once

#include <optional>
#include <string_view>

#include "drivers/camera.hpp"
#include "drivers/mono_image.hpp"

namespace cylscan::drivers {

// R8, R10, R12, R16 (unpacked, 16-bit little-endian above 8 bits) and the
// CSI-2 packed R10_CSI2P, R12_CSI2P, by libcamera's PixelFormat::toString().
std::optional<MonoFormat> libcameraMonoFormat(std::string_view name);

struct ClampedValue {
  double value = 0;
  bool clamped = false;
};

// `requested` within [minimum, maximum] (either bound may be unknown).
ClampedValue clampValue(double requested, std::optional<double> minimum,
                        std::optional<double> maximum);

// What Camera::controls() reports for a control: `value` and the bounds of
// its ControlInfo. A bound the camera does not give is the value itself (all
// that is known to work), and so are both of a pair with max below min.
ControlRange libcameraControl(double value, std::optional<double> minimum,
                              std::optional<double> maximum);

}  // namespace cylscan::drivers
