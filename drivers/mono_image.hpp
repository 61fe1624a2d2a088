// SPDX-License-Identifier: Apache-2.0
// Monochrome frames as cameras deliver them: pixel packings, the choice of a
// format by bit depth, unpacking rows into cv::Mat, and frame sequence
// counting. Pure logic shared by the V4L2 and libcamera backends.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include <opencv2/core.hpp>

namespace cylscan::drivers {

enum class MonoPacking {
  U8,       // one byte per pixel
  U16LE,    // 16-bit little-endian containers, value in the low bits (V4L2 Y10/Y12/Y16, R16)
  Csi2P10,  // MIPI CSI-2 packed 10 bit: 4 pixels in 5 bytes (V4L2 Y10P, libcamera R10_CSI2P)
  Csi2P12   // MIPI CSI-2 packed 12 bit: 2 pixels in 3 bytes (V4L2 Y12P, libcamera R12_CSI2P)
};

// One monochrome format a device offers, in the backend's own name.
struct MonoFormat {
  std::string name;  // "GREY", "Y10", "R12_CSI2P", ...
  MonoPacking packing = MonoPacking::U8;
  int bits = 8;  // significant bits per pixel
  bool operator==(const MonoFormat&) const = default;
};

// Chooses among `offered` for `requested_bits`: the exact depth (unpacked
// before packed), else the shallowest deeper one, else the deepest shallower
// one. nullopt when nothing is offered.
std::optional<std::size_t> chooseMonoFormat(std::span<const MonoFormat> offered,
                                            int requested_bits);

// Bytes a row of `width` pixels needs at least.
std::size_t minBytesPerLine(MonoPacking packing, int width);

// Copies (U8, U16LE) or unpacks (CSI-2) `height` rows of `stride` bytes into
// CV_8UC1 (bits <= 8) or CV_16UC1; values are the sensor's counts, unscaled.
// Throws std::invalid_argument when the data is too small for the geometry.
cv::Mat unpackMono(std::span<const std::uint8_t> data, int width, int height, std::size_t stride,
                   MonoPacking packing, int bits);

// Extends a device's 32-bit wrapping frame counter to 64 bits. After a stream
// restart the device counts from anew; the next frame then continues the
// count (what was lost inside the restart cannot be known from the counter).
class SequenceCounter {
 public:
  // The extended sequence number of a frame with the device's counter `raw`.
  std::uint64_t next(std::uint32_t raw);
  // Frames missing before the last one (0 when none, or after a restart).
  std::uint64_t lastGap() const { return last_gap_; }
  // The device's counter restarts (stream off and on).
  void restart() { restarted_ = true; }

 private:
  bool first_ = true;
  bool restarted_ = false;
  std::uint32_t last_raw_ = 0;
  std::uint64_t last_ = 0;
  std::uint64_t last_gap_ = 0;
};

}  // namespace cylscan::drivers
