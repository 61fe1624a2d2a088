// SPDX-License-Identifier: Apache-2.0
#include "formats/images.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgcodecs.hpp>

#include "formats/png.hpp"
#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using testing::readText;
using testing::throwsInputError;
using testing::writeText;

class ImagesTest : public testing::TempDirTest {};

bool sameFloatMaps(const cv::Mat& a, const cv::Mat& b) {
  if (a.type() != CV_32FC1 || b.type() != CV_32FC1 || a.size() != b.size()) return false;
  for (int r = 0; r < a.rows; ++r) {
    for (int c = 0; c < a.cols; ++c) {
      const float x = a.at<float>(r, c);
      const float y = b.at<float>(r, c);
      if (!((std::isnan(x) && std::isnan(y)) || x == y)) return false;
    }
  }
  return true;
}

TEST_F(ImagesTest, FloatTiffRoundTripKeepsNaN) {
  cv::Mat map(17, 23, CV_32FC1);
  cv::randu(map, -1000.0, 1000.0);
  map.at<float>(3, 4) = std::numeric_limits<float>::quiet_NaN();
  map.at<float>(16, 22) = std::numeric_limits<float>::quiet_NaN();
  map.at<float>(0, 0) = 6.2831855f;
  const fs::path file = dir_ / "depth.tiff";
  writeFloatTiff(file, map);
  const cv::Mat read = readFloatTiff(file);
  EXPECT_TRUE(sameFloatMaps(read, map));
  EXPECT_TRUE(std::isnan(read.at<float>(3, 4)));
  EXPECT_EQ(testing::entriesOf(dir_), std::vector<std::string>{"depth.tiff"});
}

TEST_F(ImagesTest, WriteFloatTiffRejectsOtherTypes) {
  EXPECT_THROW(writeFloatTiff(dir_ / "a.tiff", cv::Mat(4, 4, CV_8UC1)), std::invalid_argument);
  EXPECT_THROW(writeFloatTiff(dir_ / "a.tiff", cv::Mat(4, 4, CV_32FC3)), std::invalid_argument);
  EXPECT_THROW(writeFloatTiff(dir_ / "a.tiff", cv::Mat(4, 4, CV_64FC1)), std::invalid_argument);
  EXPECT_THROW(writeFloatTiff(dir_ / "a.tiff", cv::Mat()), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "a.tiff"));
}

TEST_F(ImagesTest, ReadFloatTiffRejectsAnIntegerTiff) {
  const fs::path file = dir_ / "int.tiff";
  ASSERT_TRUE(cv::imwrite(file.string(), cv::Mat(4, 4, CV_16UC1, cv::Scalar(7))));
  EXPECT_TRUE(
      throwsInputError([&] { readFloatTiff(file); }, file,
                       {"1-channel image of 16-bit integer", "single-channel 32-bit float"}));
}

TEST_F(ImagesTest, ReadFloatTiffRejectsAThreeChannelFloatTiff) {
  const fs::path file = dir_ / "rgb.tiff";
  ASSERT_TRUE(cv::imwrite(file.string(), cv::Mat(4, 4, CV_32FC3, cv::Scalar(1, 2, 3))));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file,
                               {"3-channel image", "expected a single-channel 32-bit float map"}));
}

// A little-endian TIFF with one IFD of LONG entries, one strip of the size
// the header implies, and no image data: the strip's offset is past the end.
std::string craftedTiff(std::uint32_t width, std::uint32_t height, std::uint32_t bits,
                        std::uint32_t samples, std::uint32_t format) {
  const auto u16 = [](std::uint32_t v) {
    return std::string{static_cast<char>(v & 0xFF), static_cast<char>((v >> 8) & 0xFF)};
  };
  const auto u32 = [&](std::uint32_t v) { return u16(v & 0xFFFF) + u16(v >> 16); };
  const std::uint64_t strip = std::uint64_t{width} * height * samples * bits / 8;
  const std::vector<std::pair<std::uint32_t, std::uint32_t>> entries{
      {256, width},
      {257, height},
      {258, bits},
      {273, 4096},
      {277, samples},
      {278, height},
      {279, static_cast<std::uint32_t>(std::min<std::uint64_t>(strip, 0xFFFFFFFFu))},
      {339, format}};
  std::string tiff =
      std::string("II*\0", 4) + u32(8) + u16(static_cast<std::uint32_t>(entries.size()));
  for (const auto& [tag, value] : entries)
    tiff += u16(tag) + u16(4) + u32(1) + u32(value);
  return tiff + u32(0);
}

TEST_F(ImagesTest, TiffHeaderClaimingAnAbsurdSizeIsRejectedBeforeDecoding) {
  const fs::path file = dir_ / "huge.tiff";
  writeText(file, craftedTiff(100000, 100000, 32, 1, 3));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"100000x100000", "limit"}));
}

TEST_F(ImagesTest, TiffHeaderWithIntegerSamples) {
  const fs::path file = dir_ / "int.tiff";
  writeText(file, craftedTiff(4, 4, 32, 1, 2));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"32-bit integer"}));
}

TEST_F(ImagesTest, TiffWithHeaderOnly) {
  const fs::path file = dir_ / "empty.tiff";
  writeText(file, craftedTiff(4, 4, 32, 1, 3));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"TIFF", "cannot decode"}));
}

TEST_F(ImagesTest, ReadFloatTiffRejectsAPng) {
  const fs::path file = dir_ / "map.tiff";
  writePng(file, cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"not a TIFF file"}));
}

TEST_F(ImagesTest, ReadFloatTiffRejectsATruncatedFile) {
  const fs::path file = dir_ / "cut.tiff";
  cv::Mat map(64, 64, CV_32FC1);
  cv::randu(map, 0.0, 1.0);
  writeFloatTiff(file, map);
  const std::string bytes = readText(file);
  writeText(file, bytes.substr(0, bytes.size() / 2));
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"TIFF"}));
}

TEST_F(ImagesTest, ReadFloatTiffMissingFile) {
  const fs::path file = dir_ / "none.tiff";
  EXPECT_TRUE(throwsInputError([&] { readFloatTiff(file); }, file, {"cannot open"}));
}

TEST_F(ImagesTest, PngRoundTrips) {
  cv::RNG rng(7);
  for (const int type : {CV_8UC1, CV_16UC1, CV_8UC3, CV_16UC3}) {
    cv::Mat image(9, 11, type);
    rng.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
    const fs::path file = dir_ / ("image" + std::to_string(type) + ".png");
    writePng(file, image);
    const cv::Mat read = readPng(file);
    ASSERT_EQ(read.type(), type);
    EXPECT_EQ(cv::norm(read, image, cv::NORM_INF), 0) << type;
  }
}

TEST_F(ImagesTest, WritePngRejectsOtherTypes) {
  EXPECT_THROW(writePng(dir_ / "a.png", cv::Mat(4, 4, CV_32FC1)), std::invalid_argument);
  EXPECT_THROW(writePng(dir_ / "a.png", cv::Mat(4, 4, CV_8UC2)), std::invalid_argument);
  EXPECT_THROW(writePng(dir_ / "a.png", cv::Mat(4, 4, CV_8UC4)), std::invalid_argument);
  EXPECT_THROW(writePng(dir_ / "a.png", cv::Mat()), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "a.png"));
  try {
    writePng(dir_ / "a.png", cv::Mat(4, 4, CV_32FC1));
    ADD_FAILURE() << "a float image was written as PNG";
  } catch (const std::invalid_argument& e) {
    // The error names the file and what PNG takes.
    EXPECT_NE(std::string(e.what()).find((dir_ / "a.png").string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("8/16-bit"), std::string::npos) << e.what();
  }
}

TEST_F(ImagesTest, WritePngReplacesAtomically) {
  const fs::path file = dir_ / "t.png";
  writePng(file, cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)));
  writePng(file, cv::Mat(5, 6, CV_8UC1, cv::Scalar(2)));
  const cv::Mat read = readPng(file);
  EXPECT_EQ(read.size(), cv::Size(6, 5));
  EXPECT_EQ(read.at<uchar>(0, 0), 2);
  EXPECT_EQ(testing::entriesOf(dir_), std::vector<std::string>{"t.png"});
}

TEST_F(ImagesTest, WriteIntoAMissingDirectoryFails) {
  EXPECT_THROW(writePng(dir_ / "no" / "t.png", cv::Mat(4, 4, CV_8UC1)), std::system_error);
}

}  // namespace
}  // namespace cylscan::formats
