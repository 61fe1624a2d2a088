// SPDX-License-Identifier: Apache-2.0
// The quasi-calibration file: QuasiCalibration::deserialize, the in-place
// QuasiCalibrationView::fromBytes and firmware::readQuasiCalibration (the
// file the daemon and the CLI load). Each input is tried as given and once
// more with its CRC-32 made right, so the checks behind the checksum are
// reached too. Only the documented exceptions may come out.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>
#include <vector>

#include "algo/quasi_calibration.hpp"
#include "firmware/reconstruction.hpp"
#include "formats/input_error.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

using cylscan::algo::QuasiCalibration;
using cylscan::algo::QuasiCalibrationView;

constexpr std::size_t kHeaderBytes = 64;
constexpr std::size_t kCrcOffset = 60;

std::uint32_t crc32(std::uint32_t crc, const std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int b = 0; b < 8; ++b)
      crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return crc;
}

// The input with the file format's CRC-32 (bytes 60..63) recomputed.
void fixCrc(std::vector<std::uint8_t>& bytes) {
  std::uint32_t crc = 0xffffffffu;
  crc = crc32(crc, bytes.data(), kCrcOffset);
  crc = crc32(crc, bytes.data() + kHeaderBytes, bytes.size() - kHeaderBytes);
  crc ^= 0xffffffffu;
  for (int i = 0; i < 4; ++i)
    bytes[kCrcOffset + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

// Uses what was read, so a calibration that passes is exercised too.
void exercise(const QuasiCalibrationView& view) {
  const cv::Size size = view.size();
  if (size.width <= 0 || size.height <= 0) throw std::logic_error("accepted an empty size");
  const std::array<float, 4> phases = {0.0f, 1.0f, -3.0f, 1e30f};
  for (int v = 0; v < std::min(size.height, 4); ++v)
    for (int u = 0; u < std::min(size.width, 4); ++u)
      for (float phi : phases) {
        (void)view.evaluate(u, v, phi);
        (void)view.depthSlope(u, v, phi);
      }
  (void)view.validCount();
}

void tryBytes(const std::vector<std::uint8_t>& bytes) {
  const auto span = std::as_bytes(std::span<const std::uint8_t>(bytes.data(), bytes.size()));
  try {
    const QuasiCalibration calib = QuasiCalibration::deserialize(span);
    exercise(calib.view());
    // A calibration that was read writes back to the same header, validity
    // plane and records (the padding after the plane is not checked on read).
    const std::vector<std::byte> again = calib.serialize();
    const std::size_t pixels = static_cast<std::size_t>(calib.size().area());
    const std::size_t records = pixels * sizeof(cylscan::algo::PixelPolynomial);
    const auto same = [&](std::size_t from, std::size_t n) {
      return std::memcmp(again.data() + from, span.data() + from, n) == 0;
    };
    if (again.size() != span.size() || !same(0, kCrcOffset) || !same(kHeaderBytes, pixels) ||
        !same(span.size() - records, records))
      throw std::logic_error("serialize(deserialize(bytes)) differs from bytes");
  } catch (const std::invalid_argument&) {
  }
  try {
    // std::vector's storage is aligned for any scalar: fromBytes may use it in place.
    exercise(QuasiCalibrationView::fromBytes(span));
  } catch (const std::invalid_argument&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> bytes(data, data + size);
  tryBytes(bytes);
  if (bytes.size() >= kHeaderBytes) {
    fixCrc(bytes);
    tryBytes(bytes);
  }

  const auto file = cylscan::fuzz::scratchDir() / "calibration.qcal";
  cylscan::fuzz::writeFile(file, cylscan::fuzz::asText(data, size));
  try {
    exercise(cylscan::firmware::readQuasiCalibration(file).view());
  } catch (const cylscan::formats::InputError&) {
  }
  return 0;
}
