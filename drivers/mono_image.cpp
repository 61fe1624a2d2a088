// SPDX-License-Identifier: Apache-2.0
#include "drivers/mono_image.hpp"

#include <stdexcept>

namespace cylscan::drivers {

std::optional<std::size_t> chooseMonoFormat(std::span<const MonoFormat> offered,
                                            int requested_bits) {
  // Rank: lower is better. Exact depth (unpacked, then packed), then deeper
  // (shallowest first), then shallower (deepest first).
  auto rank = [requested_bits](const MonoFormat& f) {
    const bool packed = f.packing == MonoPacking::Csi2P10 || f.packing == MonoPacking::Csi2P12;
    if (f.bits == requested_bits) return packed ? 1 : 0;
    if (f.bits > requested_bits) return 100 + 2 * (f.bits - requested_bits) + (packed ? 1 : 0);
    return 1000 + 2 * (requested_bits - f.bits) + (packed ? 1 : 0);
  };
  std::optional<std::size_t> best;
  for (std::size_t i = 0; i < offered.size(); ++i) {
    if (!best || rank(offered[i]) < rank(offered[*best])) best = i;
  }
  return best;
}

std::size_t minBytesPerLine(MonoPacking packing, int width) {
  const auto w = static_cast<std::size_t>(width);
  switch (packing) {
    case MonoPacking::U8:
      return w;
    case MonoPacking::U16LE:
      return 2 * w;
    case MonoPacking::Csi2P10:
      return (w + 3) / 4 * 5;
    case MonoPacking::Csi2P12:
      return (w + 1) / 2 * 3;
  }
  return 0;
}

namespace {

void unpackRow(const std::uint8_t* in, int width, MonoPacking packing, cv::Mat& out, int row) {
  if (packing == MonoPacking::U8) {
    auto* o = out.ptr<std::uint8_t>(row);
    for (int x = 0; x < width; ++x)
      o[x] = in[x];
    return;
  }
  auto* o = out.ptr<std::uint16_t>(row);
  switch (packing) {
    case MonoPacking::U16LE:
      for (int x = 0; x < width; ++x) {
        const std::uint8_t* px = in + 2 * static_cast<std::size_t>(x);
        o[x] = static_cast<std::uint16_t>(px[0] | (px[1] << 8));
      }
      break;
    case MonoPacking::Csi2P10:
      // Bytes 0–3 hold bits 9..2 of pixels 0–3; byte 4 their bits 1..0, pixel 0 lowest.
      for (int x = 0; x < width; ++x) {
        const std::uint8_t* group = in + static_cast<std::size_t>(x / 4) * 5;
        const int i = x % 4;
        o[x] = static_cast<std::uint16_t>((group[i] << 2) | ((group[4] >> (2 * i)) & 0x3));
      }
      break;
    case MonoPacking::Csi2P12:
      // Bytes 0–1 hold bits 11..4 of pixels 0–1; byte 2 their bits 3..0, pixel 0 low nibble.
      for (int x = 0; x < width; ++x) {
        const std::uint8_t* group = in + static_cast<std::size_t>(x / 2) * 3;
        const int i = x % 2;
        o[x] = static_cast<std::uint16_t>((group[i] << 4) | ((group[2] >> (4 * i)) & 0xf));
      }
      break;
    case MonoPacking::U8:
      break;
  }
}

}  // namespace

cv::Mat unpackMono(std::span<const std::uint8_t> data, int width, int height, std::size_t stride,
                   MonoPacking packing, int bits) {
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("unpackMono: image size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is empty");
  }
  const std::size_t row_bytes = minBytesPerLine(packing, width);
  if (stride < row_bytes) {
    throw std::invalid_argument("unpackMono: stride " + std::to_string(stride) +
                                " is less than a row of " + std::to_string(width) + " pixels (" +
                                std::to_string(row_bytes) + " bytes)");
  }
  const std::size_t needed = stride * static_cast<std::size_t>(height - 1) + row_bytes;
  if (data.size() < needed) {
    throw std::invalid_argument("unpackMono: " + std::to_string(data.size()) +
                                " bytes of data, a " + std::to_string(width) + "x" +
                                std::to_string(height) + " frame needs " + std::to_string(needed));
  }
  if (packing == MonoPacking::U8 && bits > 8) {
    throw std::invalid_argument("unpackMono: " + std::to_string(bits) +
                                " bits do not fit one byte per pixel");
  }
  cv::Mat out(height, width, packing == MonoPacking::U8 ? CV_8UC1 : CV_16UC1);
  for (int y = 0; y < height; ++y) {
    unpackRow(data.data() + stride * static_cast<std::size_t>(y), width, packing, out, y);
  }
  return out;
}

std::uint64_t SequenceCounter::next(std::uint32_t raw) {
  if (first_) {
    first_ = false;
    restarted_ = false;
    last_ = raw;
    last_gap_ = 0;
  } else if (restarted_) {
    restarted_ = false;
    last_ += 1;
    last_gap_ = 0;
  } else {
    // Unsigned arithmetic wraps: the distance is right across the 2^32 boundary.
    const std::uint32_t step = raw - last_raw_;
    last_gap_ = step == 0 ? 0 : step - 1;
    last_ += step;
  }
  last_raw_ = raw;
  return last_;
}

}  // namespace cylscan::drivers
