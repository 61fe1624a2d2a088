// SPDX-License-Identifier: Apache-2.0
#include "drivers/v4l2_logic.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include <linux/videodev2.h>

// Y12P (CSI-2 packed 12-bit grey) came to the uapi headers after Linux 6.1.
#ifndef V4L2_PIX_FMT_Y12P
#define V4L2_PIX_FMT_Y12P v4l2_fourcc('Y', '1', '2', 'P')
#endif

namespace cylscan::drivers {

namespace {

struct KnownFormat {
  std::uint32_t fourcc;
  MonoPacking packing;
  int bits;
};

constexpr std::array<KnownFormat, 6> kMonoFormats{{
    {V4L2_PIX_FMT_GREY, MonoPacking::U8, 8},
    {V4L2_PIX_FMT_Y10, MonoPacking::U16LE, 10},
    {V4L2_PIX_FMT_Y12, MonoPacking::U16LE, 12},
    {V4L2_PIX_FMT_Y16, MonoPacking::U16LE, 16},
    {V4L2_PIX_FMT_Y10P, MonoPacking::Csi2P10, 10},
    {V4L2_PIX_FMT_Y12P, MonoPacking::Csi2P12, 12},
}};

}  // namespace

std::string fourccName(std::uint32_t fourcc) {
  std::string out(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    out[static_cast<std::size_t>(i)] = (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  return out;
}

std::optional<MonoFormat> v4l2MonoFormat(std::uint32_t fourcc) {
  for (const KnownFormat& f : kMonoFormats) {
    if (f.fourcc == fourcc) return MonoFormat{fourccName(fourcc), f.packing, f.bits};
  }
  return std::nullopt;
}

std::uint32_t v4l2Fourcc(const MonoFormat& format) {
  for (const KnownFormat& f : kMonoFormats) {
    if (fourccName(f.fourcc) == format.name) return f.fourcc;
  }
  throw std::invalid_argument("v4l2: '" + format.name + "' is not a known monochrome format");
}

ControlValue clampToRange(std::int64_t requested, const V4l2ControlRange& range) {
  if (range.maximum < range.minimum) {
    throw std::invalid_argument("control range [" + std::to_string(range.minimum) + ", " +
                                std::to_string(range.maximum) + "] is empty");
  }
  const std::int64_t step = range.step > 0 ? range.step : 1;
  std::int64_t v = std::clamp(requested, range.minimum, range.maximum);
  const std::int64_t k = (v - range.minimum + step / 2) / step;
  v = range.minimum + k * step;
  if (v > range.maximum) v -= step;
  return {v, v != requested};
}

std::int64_t exposureUsToV4l2(double exposure_us) {
  if (!(exposure_us > 0) || !std::isfinite(exposure_us)) {
    throw std::invalid_argument("exposure " + std::to_string(exposure_us) + " µs: must be > 0");
  }
  return std::max<std::int64_t>(1, std::llround(exposure_us / 100.0));
}

double v4l2ExposureToUs(std::int64_t value) {
  return static_cast<double>(value) * 100.0;
}

std::int64_t gainToV4l2(double gain, const V4l2ControlRange& range) {
  if (!(gain > 0) || !std::isfinite(gain)) {
    throw std::invalid_argument("gain " + std::to_string(gain) + ": must be > 0");
  }
  if (gain == 1.0) return range.default_value;
  if (range.default_value <= 0) {
    throw std::invalid_argument("gain " + std::to_string(gain) + ": the gain control's default (" +
                                std::to_string(range.default_value) +
                                ") is not a unity gain to scale; use gain = 1");
  }
  return std::llround(gain * static_cast<double>(range.default_value));
}

double v4l2GainFactor(std::int64_t value, const V4l2ControlRange& range) {
  if (range.default_value <= 0) {
    throw std::invalid_argument("the gain control's default (" +
                                std::to_string(range.default_value) +
                                ") is not a unity gain to scale");
  }
  return static_cast<double>(value) / static_cast<double>(range.default_value);
}

ControlRange v4l2ExposureControl(std::int64_t value, const V4l2ControlRange& range) {
  return {v4l2ExposureToUs(value), v4l2ExposureToUs(range.minimum),
          v4l2ExposureToUs(range.maximum)};
}

ControlRange v4l2GainControl(std::int64_t value, const V4l2ControlRange& range) {
  if (range.default_value <= 0) return {1.0, 1.0, 1.0};
  return {v4l2GainFactor(value, range), v4l2GainFactor(range.minimum, range),
          v4l2GainFactor(range.maximum, range)};
}

std::chrono::nanoseconds exposureStart(std::chrono::nanoseconds buffer_timestamp,
                                       bool start_of_exposure, double exposure_us) {
  if (start_of_exposure) return buffer_timestamp;
  return buffer_timestamp - std::chrono::nanoseconds(std::llround(exposure_us * 1000.0));
}

}  // namespace cylscan::drivers
