// SPDX-License-Identifier: Apache-2.0
#include "formats/png.hpp"

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"

namespace cylscan::formats {
namespace {

constexpr std::array<unsigned char, 8> kSignature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
constexpr std::uint32_t kMaxChunkLength = 0x7FFFFFFFu;  // PNG: lengths and sizes < 2^31

constexpr std::array<std::uint32_t, 256> makeCrcTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k)
      c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = makeCrcTable();

std::uint32_t crc32(std::span<const std::byte> bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (const std::byte b : bytes)
    c = kCrcTable[(c ^ std::to_integer<std::uint32_t>(b)) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::uint32_t bigEndian32(std::span<const std::byte> bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i)
    v = (v << 8) | std::to_integer<std::uint32_t>(bytes[at + i]);
  return v;
}

std::string chunkType(std::span<const std::byte> bytes, std::size_t at) {
  std::string type;
  for (std::size_t i = 0; i < 4; ++i) {
    const char c = static_cast<char>(bytes[at + i]);
    type += (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  return type;
}

bool bitDepthAllowed(int colour_type, int bit_depth) {
  switch (colour_type) {
    case 0:
      return bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8 ||
             bit_depth == 16;
    case 3:
      return bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8;
    case 2:
    case 4:
    case 6:
      return bit_depth == 8 || bit_depth == 16;
    default:
      return false;
  }
}

std::string sizeText(std::int64_t width, std::int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// Walks the chunks after the signature up to IEND; a file that ends inside a
// chunk or before IEND is truncated.
void checkChunkStructure(std::span<const std::byte> bytes, const std::filesystem::path& file) {
  std::size_t at = kSignature.size();
  bool seen_idat = false;
  for (;;) {
    if (bytes.size() - at < 8) {
      throw InputError(file, "truncated PNG: the file ends after " + std::to_string(bytes.size()) +
                                 " bytes, before the IEND chunk");
    }
    const std::uint32_t length = bigEndian32(bytes, at);
    const std::string type = chunkType(bytes, at + 4);
    if (length > kMaxChunkLength) {
      throw InputError(file, "corrupt PNG: chunk \"" + type + "\" at byte " + std::to_string(at) +
                                 " claims " + std::to_string(length) + " bytes");
    }
    if (bytes.size() - at - 8 < std::size_t{length} + 4) {
      throw InputError(file, "truncated PNG: the file ends inside chunk \"" + type + "\" (" +
                                 std::to_string(bytes.size()) + " bytes, the chunk needs " +
                                 std::to_string(at + 12 + length) + ")");
    }
    if (type == "IDAT") seen_idat = true;
    if (type == "IEND") break;
    at += 12 + std::size_t{length};
  }
  if (!seen_idat) throw InputError(file, "corrupt PNG: no IDAT (image data) chunk");
}

}  // namespace

int PngHeader::channels() const {
  switch (colour_type) {
    case 2:
      return 3;
    case 4:
      return 2;
    case 6:
      return 4;
    default:
      return 1;
  }
}

PngHeader parsePngHeader(std::span<const std::byte> bytes, const std::filesystem::path& file,
                         const PngLimits& limits) {
  if (bytes.size() < kSignature.size() ||
      !std::equal(kSignature.begin(), kSignature.end(), bytes.begin(),
                  [](unsigned char a, std::byte b) { return std::byte{a} == b; })) {
    throw InputError(file, "not a PNG file (bad signature)");
  }
  if (bytes.size() < kPngHeaderBytes) {
    throw InputError(file, "truncated PNG: the file ends inside the IHDR header (" +
                               std::to_string(bytes.size()) + " bytes)");
  }
  if (chunkType(bytes, 12) != "IHDR" || bigEndian32(bytes, 8) != 13) {
    throw InputError(file, "corrupt PNG: the first chunk is not a 13-byte IHDR");
  }
  if (crc32(bytes.subspan(12, 17)) != bigEndian32(bytes, 29)) {
    throw InputError(file, "corrupt PNG: IHDR checksum (CRC) mismatch");
  }
  const std::uint32_t width = bigEndian32(bytes, 16);
  const std::uint32_t height = bigEndian32(bytes, 20);
  const auto byte_at = [&](std::size_t i) { return std::to_integer<int>(bytes[i]); };
  PngHeader header;
  header.bit_depth = byte_at(24);
  header.colour_type = byte_at(25);
  header.interlace = byte_at(28);
  if (width == 0 || height == 0 || width > kMaxChunkLength || height > kMaxChunkLength) {
    throw InputError(file,
                     "corrupt PNG: invalid size " + sizeText(width, height) + " in the header");
  }
  if (!bitDepthAllowed(header.colour_type, header.bit_depth)) {
    throw InputError(file, "corrupt PNG: invalid colour type " +
                               std::to_string(header.colour_type) + " with bit depth " +
                               std::to_string(header.bit_depth));
  }
  if (byte_at(26) != 0 || byte_at(27) != 0 || header.interlace > 1) {
    throw InputError(file, "corrupt PNG: unknown compression, filter or interlace method");
  }
  const auto pixels = static_cast<std::int64_t>(width) * static_cast<std::int64_t>(height);
  if (std::int64_t{width} > limits.max_width || std::int64_t{height} > limits.max_height ||
      pixels > limits.max_pixels) {
    throw InputError(file, "PNG header claims an image of " + sizeText(width, height) +
                               " pixels, beyond the limit of " +
                               sizeText(limits.max_width, limits.max_height) + " and " +
                               std::to_string(limits.max_pixels) + " pixels");
  }
  header.width = static_cast<int>(width);
  header.height = static_cast<int>(height);
  return header;
}

PngHeader readPngHeader(const std::filesystem::path& file, const PngLimits& limits) {
  const std::string prefix = readFilePrefix(file, kPngHeaderBytes);
  return parsePngHeader(std::as_bytes(std::span<const char>(prefix)), file, limits);
}

cv::Mat readPng(const std::filesystem::path& file, const PngLimits& limits, PngHeader* header_out) {
  const PngHeader header = readPngHeader(file, limits);
  // A compressed image is hardly larger than its raw samples; allow that twice
  // over plus room for ancillary chunks, and refuse to load anything bigger.
  const std::int64_t row_bytes =
      (static_cast<std::int64_t>(header.width) * header.channels() * header.bit_depth + 7) / 8 + 1;
  const std::int64_t raw_bytes = row_bytes * header.height;
  const std::string contents =
      readFileContents(file, static_cast<std::uintmax_t>(2 * raw_bytes + (16 << 20)));
  const auto bytes = std::as_bytes(std::span<const char>(contents));
  const PngHeader again = parsePngHeader(bytes, file, limits);  // the file may have changed
  if (again.width != header.width || again.height != header.height ||
      again.bit_depth != header.bit_depth || again.colour_type != header.colour_type) {
    throw InputError(file, "changed while being read");
  }
  checkChunkStructure(bytes, file);

  cv::Mat image;
  try {
    // imdecode only reads the buffer; the Mat header just cannot be built from const data.
    const cv::Mat buffer(1, static_cast<int>(contents.size()), CV_8UC1,
                         const_cast<char*>(contents.data()));
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(file, "corrupt PNG: cannot decode (" + e.msg + ")");
  }
  if (image.empty()) throw InputError(file, "corrupt PNG: the image data cannot be decoded");
  if (image.cols != header.width || image.rows != header.height) {
    throw InputError(file, "corrupt PNG: decoded to " + sizeText(image.cols, image.rows) +
                               " pixels, the header says " + sizeText(header.width, header.height));
  }
  const int expected_depth = header.bit_depth == 16 ? CV_16U : CV_8U;
  if (image.depth() != expected_depth) {
    throw InputError(file, "corrupt PNG: decoded sample depth does not match the header's " +
                               std::to_string(header.bit_depth) + " bits");
  }
  if (header_out != nullptr) *header_out = header;
  return image;
}

}  // namespace cylscan::formats
