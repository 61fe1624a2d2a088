// SPDX-License-Identifier: Apache-2.0
// Shared helpers of the formats tests: a temporary directory per test, file
// helpers, a checker for InputError, and hand-made PNG bytes.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>

#include "formats/input_error.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::formats::testing {

namespace fs = std::filesystem;

// A fresh directory for each test (test_support::TempDir), removed afterwards.
class TempDirTest : public ::testing::Test {
 protected:
  test_support::TempDir temp_;
  const fs::path dir_ = temp_.path();
};

inline std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void writeText(const fs::path& file, std::string_view text) {
  fs::create_directories(file.parent_path());
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
}

// Names of the entries of a directory (not recursive), sorted.
inline std::vector<std::string> entriesOf(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

// Success when f throws InputError for `file` whose message contains every needle.
template <class F>
::testing::AssertionResult throwsInputError(F&& f, const fs::path& file,
                                            std::initializer_list<std::string_view> needles) {
  try {
    f();
  } catch (const InputError& e) {
    const std::string message = e.what();
    if (e.file() != file) {
      return ::testing::AssertionFailure()
             << "InputError names " << e.file() << ", expected " << file << ": " << message;
    }
    if (message.find(file.string()) == std::string::npos) {
      return ::testing::AssertionFailure() << "message does not name the file: " << message;
    }
    for (const std::string_view needle : needles) {
      if (message.find(needle) == std::string::npos) {
        return ::testing::AssertionFailure() << "message lacks \"" << needle << "\": " << message;
      }
    }
    return ::testing::AssertionSuccess() << message;
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "threw another exception: " << e.what();
  }
  return ::testing::AssertionFailure() << "did not throw";
}

inline std::uint32_t crc32(std::string_view bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (const char ch : bytes) {
    c ^= static_cast<unsigned char>(ch);
    for (int k = 0; k < 8; ++k)
      c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
  }
  return c ^ 0xFFFFFFFFu;
}

inline void appendBigEndian32(std::string& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8)
    out.push_back(static_cast<char>((v >> shift) & 0xFF));
}

inline std::string pngChunk(std::string_view type, std::string_view data) {
  std::string chunk;
  appendBigEndian32(chunk, static_cast<std::uint32_t>(data.size()));
  std::string body(type);
  body += data;
  chunk += body;
  appendBigEndian32(chunk, crc32(body));
  return chunk;
}

// A PNG signature, an IHDR chunk with a valid CRC, a dummy IDAT and IEND: the
// header is well-formed, the image data is not.
inline std::string craftedPng(std::uint32_t width, std::uint32_t height, int bit_depth,
                              int colour_type) {
  std::string ihdr;
  appendBigEndian32(ihdr, width);
  appendBigEndian32(ihdr, height);
  ihdr.push_back(static_cast<char>(bit_depth));
  ihdr.push_back(static_cast<char>(colour_type));
  ihdr.append(3, '\0');  // compression, filter, interlace
  return std::string("\x89PNG\r\n\x1a\n", 8) + pngChunk("IHDR", ihdr) +
         pngChunk("IDAT", std::string(16, '\0')) + pngChunk("IEND", "");
}

}  // namespace cylscan::formats::testing
