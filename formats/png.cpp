// SPDX-License-Identifier: Apache-2.0
#include "formats/png.hpp"

#include <algorithm>
#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <csetjmp>
#include <cstdio>
#include <cstring>

#include <png.h>
#include <zlib.h>

#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/size_text.hpp"

namespace cylscan::formats {
namespace {

constexpr std::array<unsigned char, 8> kSignature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
constexpr std::uint32_t kMaxChunkLength = 0x7FFFFFFFu;  // PNG: lengths and sizes < 2^31

// The CRC of a chunk (zlib's: the same CRC-32 as PNG's).
std::uint32_t crc32(std::span<const std::byte> bytes) {
  return static_cast<std::uint32_t>(
      ::crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size())));
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

// libpng reports an error by calling its error function, which must not
// return: it copies the message and jumps back to the setjmp of the call
// into libpng. No C++ object is made between that setjmp and the jump, so
// none is skipped, and no exception ever unwinds through libpng's C frames.
struct PngIo {
  std::span<const std::byte> in;  // decoding: the file
  std::size_t at = 0;
  std::vector<unsigned char>* out = nullptr;  // encoding: the file so far
  std::array<char, 256> message{};
};

[[noreturn]] void pngError(png_structp png, png_const_charp text) {
  auto* io = static_cast<PngIo*>(png_get_error_ptr(png));
  std::snprintf(io->message.data(), io->message.size(), "%s", text);
  png_longjmp(png, 1);
}

void pngWarning(png_structp /*png*/, png_const_charp /*text*/) {}

void pngRead(png_structp png, png_bytep data, png_size_t length) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  if (io->in.size() - io->at < length) png_error(png, "the file ends inside the image data");
  std::memcpy(data, io->in.data() + io->at, length);
  io->at += length;
}

void pngWrite(png_structp png, png_bytep data, png_size_t length) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  io->out->insert(io->out->end(), data, data + length);
}

void pngFlush(png_structp /*png*/) {}

// The image a PNG decodes to, as OpenCV's codecs give it: grey one channel,
// colour (and palette) BGR, with an alpha channel BGRA; 8 bits for 8 bits
// or fewer, else 16. A transparency chunk (tRNS) adds no alpha channel.
cv::Mat decodedImage(const PngHeader& header) {
  const int depth = header.bit_depth == 16 ? CV_16U : CV_8U;
  int channels = 1;
  if (header.colour_type == 2 || header.colour_type == 3) channels = 3;
  if (header.colour_type == 4 || header.colour_type == 6) channels = 4;
  return cv::Mat(header.height, header.width, CV_MAKETYPE(depth, channels));
}

// Decodes `bytes` into `image`, already of the size and type decodedImage
// gives; the error's text otherwise. libpng applies no gamma: the samples
// are those stored.
std::optional<std::string> decodePng(std::span<const std::byte> bytes, cv::Mat& image) {
  PngIo io;
  io.in = bytes;
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.rows));
  for (int y = 0; y < image.rows; ++y)
    rows[static_cast<std::size_t>(y)] = image.ptr(y);
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &io, pngError, pngWarning);
  if (png == nullptr) return std::string("libpng cannot start");
  png_infop info = png_create_info_struct(png);
  // NOLINTNEXTLINE(cert-err52-cpp): libpng's error model; see PngIo
  if (info == nullptr || setjmp(png_jmpbuf(png)) != 0) {
    png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
    return std::string(io.message.data());
  }
  png_set_read_fn(png, &io, pngRead);
  png_set_crc_action(png, PNG_CRC_ERROR_QUIT, PNG_CRC_ERROR_QUIT);
  png_read_info(png, info);
  const int colour = png_get_color_type(png, info);
  png_set_palette_to_rgb(png);
  png_set_expand_gray_1_2_4_to_8(png);
  png_set_packing(png);
  if (png_get_bit_depth(png, info) == 16) png_set_swap(png);  // to the host's order
  if (colour == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
  if ((colour & PNG_COLOR_MASK_COLOR) != 0 || colour == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_bgr(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  if (png_get_rowbytes(png, info) != image.cols * image.elemSize() ||
      png_get_image_height(png, info) != static_cast<png_uint_32>(image.rows)) {
    png_error(png, "the decoded rows do not match the header");
  }
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return std::nullopt;
}

}  // namespace

std::vector<unsigned char> encodePng(const cv::Mat& image) {
  const bool depth_ok = image.depth() == CV_8U || image.depth() == CV_16U;
  const bool channels_ok = image.channels() == 1 || image.channels() == 3;
  if (image.empty() || !depth_ok || !channels_ok) {
    throw std::invalid_argument("PNG: the image must be non-empty, 8/16-bit, with 1 or 3 channels");
  }
  std::vector<unsigned char> out;
  out.reserve(image.total() * image.elemSize() / 2 + 1024);
  PngIo io;
  io.out = &out;
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.rows));
  for (int y = 0; y < image.rows; ++y)
    rows[static_cast<std::size_t>(y)] = const_cast<png_bytep>(image.ptr(y));  // only read
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &io, pngError, pngWarning);
  if (png == nullptr) throw std::runtime_error("PNG: libpng cannot start");
  png_infop info = png_create_info_struct(png);
  // NOLINTNEXTLINE(cert-err52-cpp): libpng's error model; see PngIo
  if (info == nullptr || setjmp(png_jmpbuf(png)) != 0) {
    png_destroy_write_struct(&png, info != nullptr ? &info : nullptr);
    throw std::runtime_error(std::string("PNG: cannot encode: ") + io.message.data());
  }
  png_set_write_fn(png, &io, pngWrite, pngFlush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols),
               static_cast<png_uint_32>(image.rows), image.depth() == CV_16U ? 16 : 8,
               image.channels() == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // Speed first: frames are written while the stage turns, and a camera's
  // noise leaves little for slower settings to win. One filter (Sub), zlib's
  // fastest level and run-length matching.
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_set_compression_level(png, Z_BEST_SPEED);
  png_set_compression_strategy(png, Z_RLE);
  png_write_info(png, info);
  if (image.channels() == 3) png_set_bgr(png);
  if (image.depth() == CV_16U) png_set_swap(png);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

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

  cv::Mat image = decodedImage(header);
  if (const auto error = decodePng(bytes, image)) {
    throw InputError(file, "corrupt PNG: cannot decode (" + *error + ")");
  }
  if (header_out != nullptr) *header_out = header;
  return image;
}

}  // namespace cylscan::formats
