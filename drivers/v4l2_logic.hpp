// SPDX-License-Identifier: Apache-2.0
// The parts of the V4L2 camera backend that need no device: which pixel
// formats are monochrome, control values and their ranges, timestamps.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "drivers/camera.hpp"
#include "drivers/mono_image.hpp"

namespace cylscan::drivers {

// "GREY", "Y10 ", ... from a V4L2 fourcc (non-printable bytes as '?').
std::string fourccName(std::uint32_t fourcc);

// The monochrome formats the backend reads: GREY, Y10, Y12, Y16 (and the
// CSI-2 packed Y10P, Y12P). nullopt for any other fourcc.
std::optional<MonoFormat> v4l2MonoFormat(std::uint32_t fourcc);
// The fourcc of a format v4l2MonoFormat() returned.
std::uint32_t v4l2Fourcc(const MonoFormat& format);

// A control's range as VIDIOC_QUERYCTRL reports it, in the control's own units.
struct V4l2ControlRange {
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
ControlValue clampToRange(std::int64_t requested, const V4l2ControlRange& range);

// V4L2_CID_EXPOSURE_ABSOLUTE counts 100 µs units.
std::int64_t exposureUsToV4l2(double exposure_us);
double v4l2ExposureToUs(std::int64_t value);

// Gain as a factor of the driver's default (1.0 = the default value, which
// sensor drivers set to unity analogue gain). Throws std::invalid_argument when
// the gain is not positive, or is not 1 and the default is not positive.
std::int64_t gainToV4l2(double gain, const V4l2ControlRange& range);

// The inverse of gainToV4l2: a control value as a factor of the default.
// Throws std::invalid_argument when the default is not positive.
double v4l2GainFactor(std::int64_t value, const V4l2ControlRange& range);

// What Camera::controls() reports for V4L2_CID_EXPOSURE_ABSOLUTE: `value` and
// the device's range in µs.
ControlRange v4l2ExposureControl(std::int64_t value, const V4l2ControlRange& range);
// What Camera::controls() reports for the gain control: `value` and the
// device's range as factors of its default. A default that is not positive
// has no unity to scale, so only gain 1 can be set (gainToV4l2): that
// reports 1 for all three.
ControlRange v4l2GainControl(std::int64_t value, const V4l2ControlRange& range);

// The start of exposure from a buffer's timestamp: start-of-exposure stamps
// are used as they are; end-of-frame stamps are moved back by the exposure
// (the readout time, which the driver does not report, is not removed).
std::chrono::nanoseconds exposureStart(std::chrono::nanoseconds buffer_timestamp,
                                       bool start_of_exposure, double exposure_us);

}  // namespace cylscan::drivers
