// SPDX-License-Identifier: Apache-2.0
#include "formats/point_cloud.hpp"

#include <bit>
#include <cmath>
#include <limits>

#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using testing::readText;
using testing::throwsInputError;
using testing::writeText;

PointCloud sampleCloud() {
  PointCloud cloud;
  cloud.xyz = {1.5f, -2.25f, 300.0f, 0.0f, 0.0f, 1e-7f, -1e6f, 7.0f, 512.125f};
  cloud.property_names = {"intensity", "quality"};
  cloud.properties = {{0.1f, 0.5f, 1.0f}, {1.0f, std::numeric_limits<float>::quiet_NaN(), 3.0f}};
  return cloud;
}

std::string littleEndian(const void* value, std::size_t size) {
  std::string bytes(static_cast<const char*>(value), size);
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
  return bytes;
}

template <class T>
std::string le(T value) {
  return littleEndian(&value, sizeof value);
}

template <class T>
std::string be(T value) {
  std::string bytes = le(value);
  std::reverse(bytes.begin(), bytes.end());
  return bytes;
}

bool sameFloat(float a, float b) {
  return (std::isnan(a) && std::isnan(b)) || a == b;
}

class PointCloudTest : public testing::TempDirTest {
 protected:
  fs::path file() const { return dir_ / "cloud.ply"; }

  ::testing::AssertionResult readFails(std::string_view contents,
                                       std::initializer_list<std::string_view> needles) {
    writeText(file(), contents);
    return throwsInputError([&] { readPly(file()); }, file(), needles);
  }
};

TEST_F(PointCloudTest, RoundTripWithExtraProperties) {
  const PointCloud cloud = sampleCloud();
  writePly(file(), cloud);
  const PointCloud read = readPly(file());
  ASSERT_EQ(read.size(), 3u);
  EXPECT_EQ(read.xyz, cloud.xyz);
  EXPECT_EQ(read.property_names, cloud.property_names);
  ASSERT_EQ(read.properties.size(), 2u);
  for (std::size_t p = 0; p < 2; ++p) {
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_TRUE(sameFloat(read.properties[p][i], cloud.properties[p][i])) << p << " " << i;
    }
  }
}

TEST_F(PointCloudTest, WritesTheHeaderOfTheSpecAndLittleEndianFloats) {
  PointCloud cloud;
  cloud.xyz = {1.0f, 2.0f, 3.0f};
  cloud.property_names = {"intensity"};
  cloud.properties = {{0.5f}};
  writePly(file(), cloud);
  const std::string expected_header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nproperty float intensity\nend_header\n";
  EXPECT_EQ(readText(file()), expected_header + le(1.0f) + le(2.0f) + le(3.0f) + le(0.5f));
}

TEST_F(PointCloudTest, EmptyCloud) {
  writePly(file(), PointCloud{});
  EXPECT_EQ(readPly(file()).size(), 0u);
}

TEST_F(PointCloudTest, WriterRejectsAnInconsistentCloud) {
  PointCloud cloud = sampleCloud();
  cloud.xyz.pop_back();
  EXPECT_THROW(writePly(file(), cloud), std::invalid_argument);
  cloud = sampleCloud();
  cloud.properties[1].pop_back();
  EXPECT_THROW(writePly(file(), cloud), std::invalid_argument);
  cloud = sampleCloud();
  cloud.property_names[0] = "x";
  EXPECT_THROW(writePly(file(), cloud), std::invalid_argument);
  cloud = sampleCloud();
  cloud.property_names[0] = "two words";
  EXPECT_THROW(writePly(file(), cloud), std::invalid_argument);
  cloud = sampleCloud();
  cloud.property_names.pop_back();
  EXPECT_THROW(writePly(file(), cloud), std::invalid_argument);
  EXPECT_FALSE(fs::exists(file()));
}

TEST_F(PointCloudTest, ReadsAscii) {
  const PointCloud cloud = [&] {
    writeText(file(),
              "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\n"
              "property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
              "end_header\n1.5 2 -3e2 255\n0 nan 7.25 0\n");
    return readPly(file());
  }();
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.xyz[0], 1.5f);
  EXPECT_EQ(cloud.xyz[2], -300.0f);
  EXPECT_TRUE(std::isnan(cloud.xyz[4]));
  EXPECT_EQ(cloud.property_names, std::vector<std::string>{"red"});
  EXPECT_EQ(cloud.properties[0], (std::vector<float>{255.0f, 0.0f}));
}

TEST_F(PointCloudTest, ReadsEveryScalarTypeAndSkipsFacesAfterVertices) {
  const std::string header =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 2\r\nproperty char a\r\n"
      "property uint8 b\r\nproperty short c\r\nproperty ushort d\r\nproperty double z\r\n"
      "property int e\r\nproperty uint f\r\nproperty float32 x\r\nproperty float64 y\r\n"
      "element face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n";
  std::string data;
  for (int i = 0; i < 2; ++i) {
    data += le(std::int8_t{-5}) + le(std::uint8_t{200}) + le(std::int16_t{-30000}) +
            le(std::uint16_t{60000}) + le(10.5 + i) + le(std::int32_t{-100000}) +
            le(std::uint32_t{4000000000u}) + le(1.25f * static_cast<float>(i)) + le(-2.0);
  }
  data += le(std::uint8_t{3}) + le(std::int32_t{0}) + le(std::int32_t{1}) + le(std::int32_t{0});
  writeText(file(), header + data);
  const PointCloud cloud = readPly(file());
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.xyz, (std::vector<float>{0.0f, -2.0f, 10.5f, 1.25f, -2.0f, 11.5f}));
  EXPECT_EQ(cloud.property_names, (std::vector<std::string>{"a", "b", "c", "d", "e", "f"}));
  EXPECT_EQ(cloud.properties[0][1], -5.0f);
  EXPECT_EQ(cloud.properties[1][1], 200.0f);
  EXPECT_EQ(cloud.properties[2][1], -30000.0f);
  EXPECT_EQ(cloud.properties[3][1], 60000.0f);
  EXPECT_EQ(cloud.properties[4][1], -100000.0f);
  EXPECT_EQ(cloud.properties[5][1], 4000000000.0f);
}

TEST_F(PointCloudTest, ReadsBigEndian) {
  writeText(file(),
            "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\n"
            "property float y\nproperty float z\nproperty ushort n\nend_header\n" +
                be(1.0f) + be(-2.5f) + be(1000.0f) + be(std::uint16_t{513}));
  const PointCloud cloud = readPly(file());
  EXPECT_EQ(cloud.xyz, (std::vector<float>{1.0f, -2.5f, 1000.0f}));
  EXPECT_EQ(cloud.properties[0][0], 513.0f);
}

const std::string kXyzHeader =
    "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
    "property float y\nproperty float z\nend_header\n";

TEST_F(PointCloudTest, TruncatedBinaryData) {
  EXPECT_TRUE(
      readFails(kXyzHeader + std::string(20, '\0'), {"truncated", "2 vertices", "20 bytes"}));
}

TEST_F(PointCloudTest, TruncatedWrittenFile) {
  writePly(file(), sampleCloud());
  const std::string bytes = readText(file());
  EXPECT_TRUE(readFails(bytes.substr(0, bytes.size() - 3), {"truncated"}));
}

TEST_F(PointCloudTest, AbsurdVertexCountIsRefusedBeforeAllocating) {
  EXPECT_TRUE(
      readFails("ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000000\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n" +
                    std::string(24, '\0'),
                {"truncated", "4000000000000000 vertices"}));
}

TEST_F(PointCloudTest, AbsurdAsciiVertexCount) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 18446744073709551615\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
                {"truncated", "18446744073709551615 vertices"}));
}

TEST_F(PointCloudTest, TruncatedAscii) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n1 2 3\n4 5\n",
                {"truncated", "2 vertices"}));
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n1 2 3\n4 5          \n",
                {"truncated", "ends inside element \"vertex\""}));
}

TEST_F(PointCloudTest, AsciiValueThatIsNotANumber) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n1 two 3\n",
                {"\"two\"", "not a number"}));
}

TEST_F(PointCloudTest, TrailingBytes) {
  EXPECT_TRUE(readFails(kXyzHeader + std::string(24 + 5, '\0'), {"5 bytes", "beyond"}));
}

TEST_F(PointCloudTest, TruncatedFaces) {
  EXPECT_TRUE(
      readFails("ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nelement face 1\n"
                "property list uchar int vertex_indices\nend_header\n" +
                    std::string(12, '\0') + le(std::uint8_t{3}) + le(std::int32_t{0}),
                {"truncated", "element \"face\""}));
}

TEST_F(PointCloudTest, ElementBeforeVertex) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int v\n"
                "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n",
                {"element \"face\" comes before \"vertex\""}));
}

TEST_F(PointCloudTest, MissingCoordinate) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float intensity\nend_header\n1 2 3\n",
                {"no property \"z\""}));
}

TEST_F(PointCloudTest, UnknownPropertyType) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty quad z\nend_header\n1 2 3\n",
                {"unknown property type \"quad\"", "header line 6"}));
}

TEST_F(PointCloudTest, ListPropertyInVertex) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nproperty list uchar float n\n"
                "end_header\n1 2 3 0\n",
                {"\"n\" is a list"}));
}

TEST_F(PointCloudTest, DuplicateProperty) {
  EXPECT_TRUE(
      readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nproperty float y\nend_header\n1 2 3 4\n",
                {"\"y\" is declared twice"}));
}

TEST_F(PointCloudTest, NotAPly) {
  EXPECT_TRUE(readFails("OFF\n3 1 0\n", {"not a PLY file"}));
}

TEST_F(PointCloudTest, NoEndHeader) {
  EXPECT_TRUE(readFails("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
                        {"no \"end_header\""}));
}

TEST_F(PointCloudTest, NoFormatLine) {
  EXPECT_TRUE(
      readFails("ply\nelement vertex 0\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n",
                {"no \"format\" line"}));
}

TEST_F(PointCloudTest, UnknownEncoding) {
  EXPECT_TRUE(
      readFails("ply\nformat binary_middle_endian 1.0\nend_header\n", {"unknown encoding"}));
}

TEST_F(PointCloudTest, BadVertexCount) {
  EXPECT_TRUE(readFails("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
                        {"count is not a non-negative integer"}));
}

TEST_F(PointCloudTest, MissingFile) {
  EXPECT_TRUE(throwsInputError([&] { readPly(file()); }, file(), {"cannot open"}));
}

}  // namespace
}  // namespace cylscan::formats
