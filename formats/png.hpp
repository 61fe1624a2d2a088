// SPDX-License-Identifier: Apache-2.0
// Safe PNG reading: the header (signature and IHDR) is parsed and checked
// against size limits before anything is decoded, the chunk structure is walked
// up to IEND so a truncated file is an error, and the decoded image must match
// the header. Used by the capture bundle reader; usable for any PNG input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include <opencv2/core.hpp>

namespace cylscan::formats {

struct PngLimits {
  int max_width = 16384;
  int max_height = 16384;
  std::int64_t max_pixels = 64LL * 1024 * 1024;
};

struct PngHeader {
  int width = 0;
  int height = 0;
  int bit_depth = 0;    // 1, 2, 4, 8 or 16
  int colour_type = 0;  // 0 grey, 2 RGB, 3 palette, 4 grey+alpha, 6 RGBA
  int interlace = 0;    // 0 none, 1 Adam7

  int channels() const;  // samples per pixel: 1, 3, 1, 2, 4 for the colour types above
};

inline constexpr std::size_t kPngHeaderBytes = 33;  // signature (8) + IHDR chunk (25)

// Parses and checks the first kPngHeaderBytes of a file: signature, IHDR chunk
// and its CRC, field values allowed by the PNG specification, size within limits.
// InputError naming `file` on any fault.
PngHeader parsePngHeader(std::span<const std::byte> bytes, const std::filesystem::path& file,
                         const PngLimits& limits);
// Reads only the first bytes of the file and parses them with parsePngHeader.
PngHeader readPngHeader(const std::filesystem::path& file, const PngLimits& limits = {});

// Reads and decodes a PNG with libpng, samples as stored (no gamma): 8-bit
// (fewer bits expanded) or 16-bit; grey 1 channel, colour and palette 3
// (BGR), with alpha 4 (BGRA). The header is checked first; a file that ends
// before IEND or fails to decode is an InputError. The header is returned in
// *header when header is not null.
cv::Mat readPng(const std::filesystem::path& file, const PngLimits& limits = {},
                PngHeader* header = nullptr);

// The PNG file of an 8/16-bit image with 1 (grey) or 3 (BGR) channels, written
// with libpng: std::invalid_argument for another image, std::runtime_error
// when libpng fails.
std::vector<unsigned char> encodePng(const cv::Mat& image);

}  // namespace cylscan::formats
