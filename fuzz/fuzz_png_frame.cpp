// SPDX-License-Identifier: Apache-2.0
// PNG frames through the bundle reader: the input is every frame of a
// one-camera bundle (6 per set, hard links of one file) whose capture.json is
// valid, so the reader's header checks and then readFrame's decoding see it;
// parsePngHeader and readPng get it directly too. The size limits are made
// small (1024×1024) so that a header declaring a huge image cannot make one
// run allocate hundreds of MB; the checks are the same code. Every fault must
// be an InputError; an image that decodes must match its header.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

#include "formats/capture_bundle.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace formats = cylscan::formats;

constexpr int kMaxSide = 1024;
constexpr std::int64_t kMaxPixels = 1024 * 1024;

const fs::path& bundleDir() {
  static const fs::path dir = [] {
    const fs::path d = cylscan::fuzz::scratchDir() / "bundle";
    std::string angles_high, angles_low;
    for (int k = 0; k < 6; ++k) {
      angles_high += (k ? ", " : "") + std::to_string(-90.0 + 0.2 * k);
      angles_low += (k ? ", " : "") + std::to_string(87.0 + 0.2 * k);
    }
    fs::create_directories(d / "main" / "high");
    fs::create_directories(d / "main" / "low");
    const fs::path first = d / "main" / "high" / "00.png";
    cylscan::fuzz::writeFile(first, "");
    for (const char* set : {"high", "low"})
      for (int k = 0; k < 6; ++k) {
        const fs::path frame = d / "main" / set / (formats::frameFileName(k, 6) + ".png");
        if (frame != first) fs::create_hard_link(first, frame);
      }
    cylscan::fuzz::writeFile(d / "capture.json",
                             "{\"format\": \"cylscan-capture-1\", \"cameras\": [\"main\"],"
                             " \"sets\": {\"high\": {\"period_deg\": 5.0, \"stage_deg\": [" +
                                 angles_high +
                                 "]}, \"low\": {\"period_deg\": 5.625, \"stage_deg\": [" +
                                 angles_low + "]}}}");
    return d;
  }();
  return dir;
}

void require(bool ok, const char* what) {
  if (!ok) throw std::logic_error(what);
}

void checkDecoded(const cv::Mat& image, const formats::PngHeader& h) {
  require(image.cols == h.width && image.rows == h.height, "decoded size differs from the header");
  require(h.width <= kMaxSide && h.height <= kMaxSide, "decoded beyond the limits");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path& dir = bundleDir();
  const fs::path frame = dir / "main" / "high" / "00.png";
  cylscan::fuzz::writeFile(frame, cylscan::fuzz::asText(data, size));  // in place: every link
  const formats::PngLimits png_limits{kMaxSide, kMaxSide, kMaxPixels};

  if (size >= formats::kPngHeaderBytes) {
    try {
      (void)formats::parsePngHeader(
          std::as_bytes(std::span<const std::uint8_t>(data, formats::kPngHeaderBytes)), frame,
          png_limits);
    } catch (const formats::InputError&) {
    }
  }
  try {
    formats::PngHeader header;
    const cv::Mat image = formats::readPng(frame, png_limits, &header);
    checkDecoded(image, header);
  } catch (const formats::InputError&) {
  }
  try {
    const formats::CaptureBundleReader reader(dir, {kMaxSide, kMaxSide, kMaxPixels});
    const cv::Mat image = reader.readFrame("main", cylscan::FringeSet::Low, 5);
    require(image.type() == CV_8UC1 || image.type() == CV_16UC1, "a frame of another type");
    require(image.size() == reader.frameSize("main"), "a frame of another size");
  } catch (const formats::InputError&) {
  }
  return 0;
}
