// SPDX-License-Identifier: Apache-2.0
#include "formats/images.hpp"

#include <algorithm>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <tiffio.h>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "formats/size_text.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxTiffBytes = std::uintmax_t{1} << 30;

// A TIFF in memory, for libtiff's client I/O: the file read (`in`) or the
// file being written (`out`), the position, and libtiff's last error.
struct TiffStream {
  std::span<const unsigned char> in;
  std::vector<unsigned char>* out = nullptr;
  toff_t at = 0;
  std::string error;

  toff_t size() const { return out != nullptr ? out->size() : in.size(); }
};

TiffStream& streamOf(thandle_t handle) {
  return *static_cast<TiffStream*>(handle);
}

tmsize_t tiffRead(thandle_t handle, void* buffer, tmsize_t n) {
  TiffStream& s = streamOf(handle);
  if (s.out != nullptr || n < 0 || s.at >= s.in.size()) return 0;
  const auto count = std::min<toff_t>(static_cast<toff_t>(n), s.in.size() - s.at);
  std::memcpy(buffer, s.in.data() + s.at, count);
  s.at += count;
  return static_cast<tmsize_t>(count);
}

tmsize_t tiffWrite(thandle_t handle, void* buffer, tmsize_t n) {
  TiffStream& s = streamOf(handle);
  if (s.out == nullptr || n < 0) return -1;
  const auto count = static_cast<std::size_t>(n);
  if (s.out->size() < s.at + count) s.out->resize(s.at + count);
  std::memcpy(s.out->data() + s.at, buffer, count);
  s.at += count;
  return n;
}

toff_t tiffSeek(thandle_t handle, toff_t offset, int whence) {
  TiffStream& s = streamOf(handle);
  if (whence == SEEK_CUR) offset += s.at;
  if (whence == SEEK_END) offset += s.size();
  s.at = offset;
  return s.at;
}

int tiffClose(thandle_t /*handle*/) {
  return 0;
}

toff_t tiffSize(thandle_t handle) {
  return streamOf(handle).size();
}

int tiffMap(thandle_t /*handle*/, void** /*base*/, toff_t* /*size*/) {
  return 0;  // no mapping: libtiff reads through tiffRead
}

void tiffUnmap(thandle_t /*handle*/, void* /*base*/, toff_t /*size*/) {}

// libtiff's errors are kept for the exception; its warnings (unknown tags
// and the like) are not a fault of the map.
int tiffError(TIFF* /*tiff*/, void* user, const char* module, const char* format, va_list args) {
  auto& s = *static_cast<TiffStream*>(user);
  char text[256];
  std::vsnprintf(text, sizeof text, format, args);
  if (s.error.empty()) s.error = std::string(module != nullptr ? module : "libtiff") + ": " + text;
  return 1;
}

int tiffWarning(TIFF* /*tiff*/, void* /*user*/, const char* /*module*/, const char* /*format*/,
                va_list /*args*/) {
  return 1;
}

struct TiffCloser {
  void operator()(TIFF* tiff) const { TIFFClose(tiff); }
};
using TiffHandle = std::unique_ptr<TIFF, TiffCloser>;

TiffHandle openTiff(TiffStream& stream, const char* mode) {
  struct OptionsFree {
    void operator()(TIFFOpenOptions* o) const { TIFFOpenOptionsFree(o); }
  };
  const std::unique_ptr<TIFFOpenOptions, OptionsFree> options(TIFFOpenOptionsAlloc());
  if (!options) return nullptr;
  TIFFOpenOptionsSetErrorHandlerExtR(options.get(), tiffError, &stream);
  TIFFOpenOptionsSetWarningHandlerExtR(options.get(), tiffWarning, &stream);
  return TiffHandle(TIFFClientOpenExt("map", mode, &stream, tiffRead, tiffWrite, tiffSeek,
                                      tiffClose, tiffSize, tiffMap, tiffUnmap, options.get()));
}

std::string sampleText(std::uint32_t channels, std::uint32_t bits, std::uint32_t format) {
  return std::to_string(channels) + "-channel image of " + std::to_string(bits) + "-bit " +
         (format == SAMPLEFORMAT_IEEEFP ? "float" : "integer") + " samples";
}

template <typename T>
std::uint32_t field(TIFF* tiff, ttag_t tag) {
  T value{};
  TIFFGetFieldDefaulted(tiff, tag, &value);
  return value;
}

}  // namespace

void writeFloatTiff(const fs::path& file, const cv::Mat& map) {
  if (map.empty() || map.type() != CV_32FC1) {
    throw std::invalid_argument("float TIFF " + file.string() +
                                ": the map must be a non-empty CV_32FC1 image");
  }
  std::vector<unsigned char> bytes;
  TiffStream stream;
  stream.out = &bytes;
  {
    const TiffHandle tiff = openTiff(stream, "w");
    bool ok = tiff != nullptr;
    if (ok) {
      TIFFSetField(tiff.get(), TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(map.cols));
      TIFFSetField(tiff.get(), TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(map.rows));
      TIFFSetField(tiff.get(), TIFFTAG_BITSPERSAMPLE, 32);
      TIFFSetField(tiff.get(), TIFFTAG_SAMPLESPERPIXEL, 1);
      TIFFSetField(tiff.get(), TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP);
      TIFFSetField(tiff.get(), TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
      TIFFSetField(tiff.get(), TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
      // Deflate without a predictor: every TIFF reader decodes it.
      TIFFSetField(tiff.get(), TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
      TIFFSetField(tiff.get(), TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(tiff.get(), 0));
      // The encoder may change the row it is given: a copy of each row.
      std::vector<float> row(static_cast<std::size_t>(map.cols));
      for (int y = 0; ok && y < map.rows; ++y) {
        std::memcpy(row.data(), map.ptr<float>(y), row.size() * sizeof(float));
        ok = TIFFWriteScanline(tiff.get(), row.data(), static_cast<std::uint32_t>(y), 0) == 1;
      }
      ok = ok && TIFFWriteDirectory(tiff.get()) == 1;
    }
    if (!ok) {
      throw std::runtime_error("cannot encode " + file.string() + ": " +
                               (stream.error.empty() ? "libtiff failed" : stream.error));
    }
  }
  writeFileAtomically(file, std::as_bytes(std::span<const unsigned char>(bytes)));
}

cv::Mat readFloatTiff(const fs::path& file) {
  const std::string data = readFileContents(file, kMaxTiffBytes);
  if (data.size() < 4 || !(data.compare(0, 2, "II") == 0 || data.compare(0, 2, "MM") == 0)) {
    throw InputError(file, "not a TIFF file (bad signature)");
  }
  TiffStream stream;
  stream.in = std::span(reinterpret_cast<const unsigned char*>(data.data()), data.size());
  // "m": no memory mapping (tiffMap maps nothing anyway).
  const TiffHandle tiff = openTiff(stream, "rm");
  if (!tiff) throw InputError(file, "corrupt TIFF: " + stream.error);
  const std::uint32_t width = field<std::uint32_t>(tiff.get(), TIFFTAG_IMAGEWIDTH);
  const std::uint32_t height = field<std::uint32_t>(tiff.get(), TIFFTAG_IMAGELENGTH);
  const std::uint32_t samples = field<std::uint16_t>(tiff.get(), TIFFTAG_SAMPLESPERPIXEL);
  const std::uint32_t bits = field<std::uint16_t>(tiff.get(), TIFFTAG_BITSPERSAMPLE);
  const std::uint32_t format = field<std::uint16_t>(tiff.get(), TIFFTAG_SAMPLEFORMAT);
  // The limits of a map are those of a frame (PngLimits), checked before
  // anything is allocated for the samples.
  const PngLimits limits;
  const auto pixels = std::int64_t{width} * std::int64_t{height};
  if (width == 0 || height == 0) throw InputError(file, "corrupt TIFF: no image size");
  if (std::int64_t{width} > limits.max_width || std::int64_t{height} > limits.max_height ||
      pixels > limits.max_pixels) {
    throw InputError(file, "TIFF header claims an image of " + sizeText(width, height) +
                               " pixels, beyond the limit of " +
                               sizeText(limits.max_width, limits.max_height) + " and " +
                               std::to_string(limits.max_pixels) + " pixels");
  }
  if (samples != 1 || bits != 32 || format != SAMPLEFORMAT_IEEEFP) {
    throw InputError(file, "holds a " + sampleText(samples, bits, format) +
                               "; expected a single-channel 32-bit float map");
  }
  if (TIFFIsTiled(tiff.get()) != 0) {
    throw InputError(file, "is a tiled TIFF; a map is read only in strips");
  }
  if (TIFFScanlineSize64(tiff.get()) != std::uint64_t{width} * sizeof(float)) {
    throw InputError(file, "corrupt TIFF: its rows are not " + std::to_string(width) + " floats");
  }
  cv::Mat image(static_cast<int>(height), static_cast<int>(width), CV_32FC1);
  for (std::uint32_t y = 0; y < height; ++y) {
    if (TIFFReadScanline(tiff.get(), image.ptr(static_cast<int>(y)), y, 0) != 1) {
      throw InputError(file, "corrupt or truncated TIFF: cannot decode row " + std::to_string(y) +
                                 (stream.error.empty() ? "" : " (" + stream.error + ")"));
    }
  }
  return image;
}

void writePng(const fs::path& file, const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  try {
    bytes = encodePng(image);
  } catch (const std::invalid_argument& e) {
    // encodePng's rule for what it takes, with the file it was for.
    throw std::invalid_argument(file.string() + ": " + e.what());
  }
  writeFileAtomically(file, std::as_bytes(std::span<const unsigned char>(bytes)));
}

}  // namespace cylscan::formats
