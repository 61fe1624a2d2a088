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

constexpr std::size_t kCrcOffset = 60;
constexpr std::size_t kCrcResumes = 64;  // the CRC covers [0, 60) and [64, end)
constexpr std::size_t kHeaderBytesV1 = 64;
constexpr std::size_t kHeaderBytes = 72;  // what serialize() writes (version 2)

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
  crc = crc32(crc, bytes.data() + kCrcResumes, bytes.size() - kCrcResumes);
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
    // A calibration that was read writes back to the same header fields,
    // validity plane and records (the padding after the plane is not checked
    // on read). It is written as version 2: a version-1 file (64-byte header,
    // no order-residual fields) comes back 8 bytes longer with its version
    // and header size changed, everything else the same.
    const std::vector<std::byte> again = calib.serialize();
    const bool v1 = bytes[8] == 1;
    const std::size_t header = v1 ? kHeaderBytesV1 : kHeaderBytes;
    const std::size_t pixels = static_cast<std::size_t>(calib.size().area());
    const std::size_t records = pixels * sizeof(cylscan::algo::PixelPolynomial);
    const auto same = [&](std::size_t out, std::size_t in, std::size_t n) {
      return std::memcmp(again.data() + out, span.data() + in, n) == 0;
    };
    const bool fields = v1 ? same(0, 0, 8) && same(16, 16, kCrcOffset - 16)
                           : same(0, 0, kCrcOffset) && same(64, 64, kHeaderBytes - 64);
    if (again.size() != span.size() - header + kHeaderBytes || !fields ||
        !same(kHeaderBytes, header, pixels) ||
        !same(again.size() - records, span.size() - records, records))
      throw std::logic_error("serialize(deserialize(bytes)) differs from bytes");
    if (QuasiCalibration::deserialize(again).serialize() != again)
      throw std::logic_error("a version-2 file does not write back byte for byte");
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
  if (bytes.size() >= kCrcResumes) {
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
