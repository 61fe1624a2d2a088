// SPDX-License-Identifier: Apache-2.0
#include "formats/images.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxTiffBytes = std::uintmax_t{1} << 30;

void encodeAndWrite(const fs::path& file, const std::string& extension, const cv::Mat& image) {
  std::vector<uchar> buffer;
  bool ok = false;
  try {
    ok = cv::imencode(extension, image, buffer);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot encode " + file.string() + ": " + e.err);
  }
  if (!ok) throw std::runtime_error("cannot encode " + file.string());
  writeFileAtomically(file, std::as_bytes(std::span<const uchar>(buffer)));
}

// The limits of a map read by readFloatTiff (those of PngLimits).
// What readFloatTiff needs from the first image file directory (IFD) of a TIFF,
// read before anything is decoded so that a header claiming an absurd size or
// another sample type is refused without allocating.
struct TiffHeader {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t samples_per_pixel = 1;  // TIFF defaults
  std::uint32_t bits_per_sample = 1;
  std::uint32_t sample_format = 1;  // 1 unsigned, 2 signed, 3 IEEE float
};

class TiffHeaderParser {
 public:
  TiffHeaderParser(const fs::path& file, const std::string& data) : file_(file), data_(data) {}

  TiffHeader parse() const {
    if (data_.size() < 8 || !(data_.compare(0, 2, "II") == 0 || data_.compare(0, 2, "MM") == 0)) {
      fail("not a TIFF file (bad signature)");
    }
    if (unsigned16(2) != 42) fail("not a classic TIFF file (BigTIFF and others are not supported)");
    const std::size_t ifd = unsigned32(4);
    if (ifd < 8 || ifd > data_.size() - 2) fail("corrupt TIFF: the first IFD is outside the file");
    const std::size_t entries = unsigned16(ifd);
    if (entries > (data_.size() - ifd - 2) / 12) fail("truncated TIFF: the first IFD is cut off");
    TiffHeader header;
    bool has_width = false;
    bool has_height = false;
    for (std::size_t i = 0; i < entries; ++i) {
      const std::size_t at = ifd + 2 + 12 * i;
      const std::uint32_t tag = unsigned16(at);
      const std::uint32_t count = unsigned32(at + 4);
      const auto value = [&] { return firstValue(at, count); };
      switch (tag) {
        case 256:
          header.width = value();
          has_width = true;
          break;
        case 257:
          header.height = value();
          has_height = true;
          break;
        case 258:  // one value per sample; only the first matters to refuse others
          header.bits_per_sample = value();
          break;
        case 277:
          header.samples_per_pixel = value();
          break;
        case 339:
          header.sample_format = value();
          break;
        default:
          break;
      }
    }
    if (!has_width || !has_height || header.width == 0 || header.height == 0) {
      fail("corrupt TIFF: no image size in the first IFD");
    }
    return header;
  }

 private:
  [[noreturn]] void fail(const std::string& fault) const { throw InputError(file_, fault); }

  bool bigEndian() const { return data_[0] == 'M'; }

  std::uint32_t unsigned16(std::size_t at) const {
    const auto b0 = static_cast<unsigned char>(data_[at]);
    const auto b1 = static_cast<unsigned char>(data_[at + 1]);
    return bigEndian() ? (b0 << 8u) | b1 : (b1 << 8u) | b0;
  }

  std::uint32_t unsigned32(std::size_t at) const {
    const std::uint32_t a = unsigned16(at);
    const std::uint32_t b = unsigned16(at + 2);
    return bigEndian() ? (a << 16u) | b : (b << 16u) | a;
  }

  // The first SHORT or LONG value of an entry: in the entry itself when all
  // values fit in its 4 bytes, else at the offset the entry holds.
  std::uint32_t firstValue(std::size_t entry, std::uint32_t count) const {
    const std::uint32_t type = unsigned16(entry + 2);
    const std::size_t size = type == 3 ? 2 : 4;
    if (count == 0 || (type != 3 && type != 4)) {
      fail("corrupt TIFF: tag " + std::to_string(unsigned16(entry)) + " is not a number");
    }
    std::size_t at = entry + 8;
    if (std::uint64_t{count} * size > 4) {
      at = unsigned32(entry + 8);
      if (at > data_.size() - size) {
        fail("corrupt TIFF: tag " + std::to_string(unsigned16(entry)) + " points outside the file");
      }
    }
    return size == 2 ? unsigned16(at) : unsigned32(at);
  }

  const fs::path& file_;
  const std::string& data_;
};

std::string sampleText(std::uint32_t channels, std::uint32_t bits, std::uint32_t format) {
  return std::to_string(channels) + "-channel image of " + std::to_string(bits) + "-bit " +
         (format == 3 ? "float" : "integer") + " samples";
}

TiffHeader checkFloatTiffHeader(const fs::path& file, const std::string& data,
                                const PngLimits& limits) {
  const TiffHeader header = TiffHeaderParser(file, data).parse();
  const auto pixels = std::int64_t{header.width} * std::int64_t{header.height};
  if (std::int64_t{header.width} > limits.max_width ||
      std::int64_t{header.height} > limits.max_height || pixels > limits.max_pixels) {
    throw InputError(file, "TIFF header claims an image of " + std::to_string(header.width) + "x" +
                               std::to_string(header.height) + " pixels, beyond the limit of " +
                               std::to_string(limits.max_width) + "x" +
                               std::to_string(limits.max_height) + " and " +
                               std::to_string(limits.max_pixels) + " pixels");
  }
  if (header.samples_per_pixel != 1 || header.bits_per_sample != 32 || header.sample_format != 3) {
    throw InputError(file, "holds a " +
                               sampleText(header.samples_per_pixel, header.bits_per_sample,
                                          header.sample_format) +
                               "; expected a single-channel 32-bit float map");
  }
  return header;
}

}  // namespace

void writeFloatTiff(const fs::path& file, const cv::Mat& map) {
  if (map.empty() || map.type() != CV_32FC1) {
    throw std::invalid_argument("float TIFF " + file.string() +
                                ": the map must be a non-empty CV_32FC1 image");
  }
  encodeAndWrite(file, ".tiff", map);
}

cv::Mat readFloatTiff(const fs::path& file) {
  const std::string data = readFileContents(file, kMaxTiffBytes);
  const TiffHeader header = checkFloatTiffHeader(file, data, PngLimits{});
  cv::Mat image;
  try {
    // imdecode only reads the buffer; the Mat header just cannot be built from const data.
    const cv::Mat buffer(1, static_cast<int>(data.size()), CV_8UC1, const_cast<char*>(data.data()));
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(file, "corrupt TIFF: cannot decode (" + e.err + ")");
  }
  if (image.empty()) throw InputError(file, "corrupt or truncated TIFF: cannot decode the image");
  if (image.cols != static_cast<int>(header.width) ||
      image.rows != static_cast<int>(header.height)) {
    throw InputError(file, "corrupt TIFF: decoded to another size than the header says");
  }
  if (image.type() != CV_32FC1) {
    throw InputError(file, "holds a " + std::to_string(image.channels()) + "-channel image of " +
                               (image.depth() == CV_32F
                                    ? std::string("32-bit float")
                                    : std::to_string(8 * image.elemSize1()) + "-bit integer") +
                               " samples; expected a single-channel 32-bit float map");
  }
  return image;
}

void writePng(const fs::path& file, const cv::Mat& image) {
  const bool depth_ok = image.depth() == CV_8U || image.depth() == CV_16U;
  const bool channels_ok = image.channels() == 1 || image.channels() == 3;
  if (image.empty() || !depth_ok || !channels_ok) {
    throw std::invalid_argument("PNG " + file.string() +
                                ": the image must be non-empty, 8/16-bit, with 1 or 3 channels");
  }
  encodeAndWrite(file, ".png", image);
}

}  // namespace cylscan::formats
