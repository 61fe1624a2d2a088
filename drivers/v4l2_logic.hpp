// SPDX-License-Identifier: Apache-2.0
// The parts of the V4L2 camera backend that need no device: which pixel
// formats are monochrome, control values and their ranges, timestamps.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "drivers/mono_image.hpp"

namespace cylscan::drivers {

// "GREY", "Y10 ", ... from a V4L2 fourcc (non-printable bytes as '?').
std::string fourccName(std::uint32_t fourcc);

// The monochrome formats the backend reads: GREY, Y10, Y12, Y16 (and the
// CSI-2 packed Y10P, Y12P). nullopt for any other fourcc.
std::optional<MonoFormat> v4l2MonoFormat(std::uint32_t fourcc);
// The fourcc of a format v4l2MonoFormat() returned.
std::uint32_t v4l2Fourcc(const MonoFormat& format);

// A control's range as VIDIOC_QUERYCTRL reports it.
struct ControlRange {
  std::int64_t minimum = 0;
  std::int64_t maximum = 0;
  std::int64_t step = 1;
  std::int64_t default_value = 0;
};

struct ControlValue {
  std::int64_t value = 0;  // what is written to the device
  bool clamped = false;    // the request was outside the range or off the step grid
};

// The nearest value of the range's grid (minimum + k·step) within [minimum, maximum].
ControlValue clampToRange(std::int64_t requested, const ControlRange& range);

// V4L2_CID_EXPOSURE_ABSOLUTE counts 100 µs units.
std::int64_t exposureUsToV4l2(double exposure_us);
double v4l2ExposureToUs(std::int64_t value);

// Gain as a factor of the driver's default (1.0 = the default value, which
// sensor drivers set to unity analogue gain). Throws std::invalid_argument when
// the gain is not positive, or is not 1 and the default is not positive.
std::int64_t gainToV4l2(double gain, const ControlRange& range);

// The start of exposure from a buffer's timestamp: start-of-exposure stamps
// are used as they are; end-of-frame stamps are moved back by the exposure
// (the readout time, which the driver does not report, is not removed).
std::chrono::nanoseconds exposureStart(std::chrono::nanoseconds buffer_timestamp,
                                       bool start_of_exposure, double exposure_us);

}  // namespace cylscan::drivers
