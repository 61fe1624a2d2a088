// SPDX-License-Identifier: Apache-2.0
#include "formats/png.hpp"

#include <opencv2/imgcodecs.hpp>

#include "formats/images.hpp"
#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using testing::craftedPng;
using testing::readText;
using testing::throwsInputError;
using testing::writeText;

class PngTest : public testing::TempDirTest {};

TEST_F(PngTest, ReadsTheHeaderOfARealFile) {
  const fs::path file = dir_ / "a.png";
  writePng(file, cv::Mat(5, 9, CV_16UC1, cv::Scalar(1000)));
  const PngHeader header = readPngHeader(file);
  EXPECT_EQ(header.width, 9);
  EXPECT_EQ(header.height, 5);
  EXPECT_EQ(header.bit_depth, 16);
  EXPECT_EQ(header.colour_type, 0);
  EXPECT_EQ(header.channels(), 1);
}

TEST_F(PngTest, ReadsColourImagesAsStored) {
  const fs::path file = dir_ / "c.png";
  const cv::Mat image(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  writePng(file, image);
  PngHeader header;
  const cv::Mat read = readPng(file, {}, &header);
  EXPECT_EQ(header.colour_type, 2);
  EXPECT_EQ(header.channels(), 3);
  ASSERT_EQ(read.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(read, image, cv::NORM_INF), 0);
}

TEST_F(PngTest, AbsurdSizeIsRejectedFromTheHeaderAlone) {
  const fs::path file = dir_ / "huge.png";
  writeText(file, craftedPng(100000, 100000, 16, 0));
  EXPECT_TRUE(throwsInputError([&] { readPngHeader(file); }, file, {"100000x100000", "limit"}));
  EXPECT_TRUE(throwsInputError([&] { readPng(file); }, file, {"100000x100000"}));
}

TEST_F(PngTest, WidthBeyondTheLimit) {
  const fs::path file = dir_ / "wide.png";
  writeText(file, craftedPng(20000, 2, 8, 0));
  EXPECT_TRUE(throwsInputError([&] { readPngHeader(file); }, file, {"20000x2"}));
}

TEST_F(PngTest, ZeroSize) {
  const fs::path file = dir_ / "zero.png";
  writeText(file, craftedPng(0, 10, 8, 0));
  EXPECT_TRUE(throwsInputError([&] { readPngHeader(file); }, file, {"invalid size 0x10"}));
}

TEST_F(PngTest, BadSignature) {
  const fs::path file = dir_ / "x.png";
  writeText(file, "GIF89a and more bytes to make it long enough for a header");
  EXPECT_TRUE(throwsInputError([&] { readPngHeader(file); }, file, {"not a PNG file"}));
}

TEST_F(PngTest, HeaderChecksumMismatch) {
  const fs::path file = dir_ / "x.png";
  std::string bytes = craftedPng(8, 8, 8, 0);
  bytes[19] = 9;  // width 8 -> 9 without fixing the CRC
  writeText(file, bytes);
  EXPECT_TRUE(throwsInputError([&] { readPngHeader(file); }, file, {"IHDR", "CRC", "mismatch"}));
}

TEST_F(PngTest, InvalidBitDepthForColourType) {
  const fs::path file = dir_ / "x.png";
  writeText(file, craftedPng(8, 8, 4, 2));
  EXPECT_TRUE(
      throwsInputError([&] { readPngHeader(file); }, file, {"colour type 2", "bit depth 4"}));
}

TEST_F(PngTest, TruncatedHalfFile) {
  const fs::path file = dir_ / "t.png";
  cv::Mat image(64, 64, CV_8UC1);
  cv::randu(image, 0, 256);
  writePng(file, image);
  const std::string bytes = readText(file);
  writeText(file, bytes.substr(0, bytes.size() / 2));
  EXPECT_NO_THROW(readPngHeader(file));
  EXPECT_TRUE(throwsInputError([&] { readPng(file); }, file, {"truncated PNG"}));
}

TEST_F(PngTest, MissingIend) {
  const fs::path file = dir_ / "t.png";
  writePng(file, cv::Mat(4, 4, CV_8UC1, cv::Scalar(3)));
  const std::string bytes = readText(file);
  writeText(file, bytes.substr(0, bytes.size() - 12));  // IEND is the last 12 bytes
  EXPECT_TRUE(throwsInputError([&] { readPng(file); }, file, {"truncated PNG", "IEND"}));
}

TEST_F(PngTest, MissingFile) {
  const fs::path file = dir_ / "none.png";
  EXPECT_TRUE(throwsInputError([&] { readPng(file); }, file, {"cannot open"}));
}

TEST_F(PngTest, DirectoryInsteadOfAFile) {
  const fs::path file = dir_ / "d.png";
  fs::create_directories(file);
  EXPECT_TRUE(throwsInputError([&] { readPng(file); }, file, {"is a directory"}));
}

}  // namespace
}  // namespace cylscan::formats
