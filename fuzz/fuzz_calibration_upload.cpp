// SPDX-License-Identifier: Apache-2.0
// The calibration upload (PUT /api/v1/calibration/{camera}): the body as the
// HTTP layer hands it to ScanService::installCalibration for the main camera
// of a tiny virtual head (16×16, so a whole valid calibration is 15 KB and
// the fuzzer can reach the install). A fault must be ServiceError 400
// (corrupt) or 422 (another image size); an accepted file must be installed
// byte for byte. The CRC-32 of the input is made right first when the input
// starts with '+', so the checks behind the checksum are reached.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzz/fuzz_support.hpp"
#include "fuzz/small_service.hpp"

namespace {

constexpr std::size_t kHeaderBytes = 64;
constexpr std::size_t kCrcOffset = 60;

std::uint32_t crc32(std::uint32_t crc, const char* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= static_cast<unsigned char>(p[i]);
    for (int b = 0; b < 8; ++b)
      crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return crc;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string body(cylscan::fuzz::asText(data, size));
  if (!body.empty() && body.front() == '+') {
    body.erase(0, 1);
    if (body.size() >= kHeaderBytes) {
      std::uint32_t crc = crc32(0xffffffffu, body.data(), kCrcOffset);
      crc = crc32(crc, body.data() + kHeaderBytes, body.size() - kHeaderBytes) ^ 0xffffffffu;
      for (int i = 0; i < 4; ++i)
        body[kCrcOffset + i] = static_cast<char>(crc >> (8 * i));
    }
  }
  auto& service = cylscan::fuzz::smallService();
  try {
    const nlohmann::json info = service.installCalibration("main", body);
    if (info.value("width", 0) != cylscan::fuzz::kSmallWidth ||
        info.value("height", 0) != cylscan::fuzz::kSmallHeight)
      throw std::logic_error("installed a calibration of another size");
    const std::optional<std::filesystem::path> file = service.calibrationFile("main");
    if (!file || cylscan::fuzz::readFile(*file) != body)
      throw std::logic_error("the installed file differs from the upload");
  } catch (const cylscan::firmware::ServiceError& e) {
    if (e.httpStatus() != 400 && e.httpStatus() != 422)
      throw std::logic_error("a bad upload not answered 400 or 422");
  }
  return 0;
}
