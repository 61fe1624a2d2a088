// SPDX-License-Identifier: Apache-2.0
#include "drivers/mono_image.hpp"

#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace cylscan::drivers {
namespace {

const MonoFormat kGrey{"GREY", MonoPacking::U8, 8};
const MonoFormat kY10{"Y10 ", MonoPacking::U16LE, 10};
const MonoFormat kY10P{"Y10P", MonoPacking::Csi2P10, 10};
const MonoFormat kY12{"Y12 ", MonoPacking::U16LE, 12};
const MonoFormat kY12P{"Y12P", MonoPacking::Csi2P12, 12};
const MonoFormat kY16{"Y16 ", MonoPacking::U16LE, 16};

std::optional<MonoFormat> choose(const std::vector<MonoFormat>& offered, int bits) {
  const auto i = chooseMonoFormat(offered, bits);
  if (!i) return std::nullopt;
  return offered[*i];
}

TEST(MonoFormatChoice, ExactDepthFirstUnpackedBeforePacked) {
  const std::vector<MonoFormat> all{kY16, kY10P, kGrey, kY12P, kY10, kY12};
  EXPECT_EQ(choose(all, 8), kGrey);
  EXPECT_EQ(choose(all, 10), kY10);
  EXPECT_EQ(choose(all, 12), kY12);
  EXPECT_EQ(choose(all, 16), kY16);
  EXPECT_EQ(choose({kY10P, kGrey}, 10), kY10P);
}

TEST(MonoFormatChoice, ElseTheShallowestDeeperElseTheDeepestShallower) {
  EXPECT_EQ(choose({kY16, kY12P, kGrey}, 10), kY12P);
  EXPECT_EQ(choose({kY16, kY12, kY12P}, 10), kY12);
  EXPECT_EQ(choose({kGrey, kY10}, 12), kY10);
  EXPECT_EQ(choose({kGrey}, 16), kGrey);
  EXPECT_EQ(choose({}, 8), std::nullopt);
}

TEST(MonoUnpack, EightBitRowsWithPadding) {
  const int width = 5, height = 3;
  const std::size_t stride = 8;
  std::vector<std::uint8_t> data(stride * height, 0xEE);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      data[stride * y + x] = static_cast<std::uint8_t>(10 * y + x);
  const cv::Mat m = unpackMono(data, width, height, stride, MonoPacking::U8, 8);
  ASSERT_EQ(m.type(), CV_8UC1);
  ASSERT_EQ(m.size(), cv::Size(width, height));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      EXPECT_EQ(m.at<std::uint8_t>(y, x), 10 * y + x);
}

TEST(MonoUnpack, SixteenBitLittleEndianContainers) {
  const int width = 3, height = 2;
  const std::size_t stride = 8;
  std::vector<std::uint8_t> data(stride * height, 0);
  const std::uint16_t values[2][3] = {{0, 1023, 0x155}, {4095, 0x0102, 513}};
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      data[stride * y + 2 * x] = values[y][x] & 0xff;
      data[stride * y + 2 * x + 1] = values[y][x] >> 8;
    }
  }
  const cv::Mat m = unpackMono(data, width, height, stride, MonoPacking::U16LE, 12);
  ASSERT_EQ(m.type(), CV_16UC1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      EXPECT_EQ(m.at<std::uint16_t>(y, x), values[y][x]);
}

TEST(MonoUnpack, Csi2Packed10KnownBytes) {
  // Pixels 0x3FF, 0x000, 0x155, 0x2AA: high bytes FF 00 55 AA, low bits 3, 0, 1, 2
  // in byte 4 from bit 0: 0b10'01'00'11 = 0x93.
  const std::vector<std::uint8_t> data{0xFF, 0x00, 0x55, 0xAA, 0x93};
  const cv::Mat m = unpackMono(data, 4, 1, 5, MonoPacking::Csi2P10, 10);
  ASSERT_EQ(m.type(), CV_16UC1);
  EXPECT_EQ(m.at<std::uint16_t>(0, 0), 0x3FF);
  EXPECT_EQ(m.at<std::uint16_t>(0, 1), 0x000);
  EXPECT_EQ(m.at<std::uint16_t>(0, 2), 0x155);
  EXPECT_EQ(m.at<std::uint16_t>(0, 3), 0x2AA);
}

TEST(MonoUnpack, Csi2Packed12KnownBytes) {
  // Pixels 0xABC, 0x123: high bytes AB 12, low nibbles C (pixel 0) and 3 (pixel 1): 0x3C.
  const std::vector<std::uint8_t> data{0xAB, 0x12, 0x3C};
  const cv::Mat m = unpackMono(data, 2, 1, 3, MonoPacking::Csi2P12, 12);
  EXPECT_EQ(m.at<std::uint16_t>(0, 0), 0xABC);
  EXPECT_EQ(m.at<std::uint16_t>(0, 1), 0x123);
}

// Packs like a CSI-2 receiver (written from the bit layout, independently of
// the unpacker), with a stride longer than a row and a width that does not
// fill the last group.
std::vector<std::uint8_t> pack(const cv::Mat& img, int bits, std::size_t stride) {
  std::vector<std::uint8_t> out(stride * img.rows, 0x5A);
  const int per_group = bits == 10 ? 4 : 2;
  const int group_bytes = bits == 10 ? 5 : 3;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const unsigned v = img.at<std::uint16_t>(y, x);
      const std::size_t group = stride * y + static_cast<std::size_t>(x / per_group) * group_bytes;
      const int i = x % per_group;
      const int low_bits = bits - 8;
      out[group + i] = static_cast<std::uint8_t>(v >> low_bits);
      std::uint8_t& lows = out[group + per_group];
      if (i == 0) lows = 0;
      lows |= static_cast<std::uint8_t>((v & ((1U << low_bits) - 1)) << (low_bits * i));
    }
  }
  return out;
}

TEST(MonoUnpack, Csi2PackedRoundTrip) {
  std::mt19937 rng(5);
  for (int bits : {10, 12}) {
    const int width = 13, height = 7;
    cv::Mat img(height, width, CV_16UC1);
    std::uniform_int_distribution<int> value(0, (1 << bits) - 1);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        img.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(value(rng));
    const MonoPacking packing = bits == 10 ? MonoPacking::Csi2P10 : MonoPacking::Csi2P12;
    const std::size_t stride = minBytesPerLine(packing, width) + 3;
    const cv::Mat back = unpackMono(pack(img, bits, stride), width, height, stride, packing, bits);
    EXPECT_EQ(cv::countNonZero(back != img), 0) << bits << " bits";
  }
}

TEST(MonoUnpack, RowSizes) {
  EXPECT_EQ(minBytesPerLine(MonoPacking::U8, 7), 7U);
  EXPECT_EQ(minBytesPerLine(MonoPacking::U16LE, 7), 14U);
  EXPECT_EQ(minBytesPerLine(MonoPacking::Csi2P10, 8), 10U);
  EXPECT_EQ(minBytesPerLine(MonoPacking::Csi2P10, 9), 15U);
  EXPECT_EQ(minBytesPerLine(MonoPacking::Csi2P12, 4), 6U);
  EXPECT_EQ(minBytesPerLine(MonoPacking::Csi2P12, 5), 9U);
}

TEST(MonoUnpack, RejectsDataThatDoesNotFitTheGeometry) {
  const std::vector<std::uint8_t> data(10 * 4 - 1);
  EXPECT_THROW(unpackMono(data, 10, 4, 10, MonoPacking::U8, 8), std::invalid_argument);
  EXPECT_EQ(unpackMono(data, 10, 3, 10, MonoPacking::U8, 8).rows, 3);
  EXPECT_EQ(unpackMono(data, 9, 4, 10, MonoPacking::U8, 8).rows, 4)
      << "the last row needs only its pixels, not a whole stride";
  EXPECT_THROW(unpackMono(data, 10, 3, 9, MonoPacking::U8, 8),
               std::invalid_argument);  // stride < row
  EXPECT_THROW(unpackMono(data, 0, 3, 10, MonoPacking::U8, 8), std::invalid_argument);
  EXPECT_THROW(unpackMono(data, 4, 4, 4, MonoPacking::U8, 10), std::invalid_argument);
}

TEST(SequenceCounter, CountsGapsAndWraps) {
  SequenceCounter c;
  EXPECT_EQ(c.next(7), 7U);
  EXPECT_EQ(c.lastGap(), 0U);
  EXPECT_EQ(c.next(8), 8U);
  EXPECT_EQ(c.next(11), 11U);
  EXPECT_EQ(c.lastGap(), 2U);
  // The device's 32-bit counter wraps; the extended count goes on.
  SequenceCounter w;
  EXPECT_EQ(w.next(0xFFFFFFFEU), 0xFFFFFFFEU);
  EXPECT_EQ(w.next(0xFFFFFFFFU), 0xFFFFFFFFU);
  EXPECT_EQ(w.next(1U), 0x100000001U);
  EXPECT_EQ(w.lastGap(), 1U);
}

TEST(SequenceCounter, ContinuesAfterARestart) {
  SequenceCounter c;
  c.next(40);
  c.next(41);
  c.restart();
  EXPECT_EQ(c.next(0), 42U);  // the device counts from 0 again
  EXPECT_EQ(c.lastGap(), 0U);
  EXPECT_EQ(c.next(2), 44U);
  EXPECT_EQ(c.lastGap(), 1U);
}

}  // namespace
}  // namespace cylscan::drivers
