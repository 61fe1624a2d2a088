// SPDX-License-Identifier: Apache-2.0
// The merged cloud of several cameras (docs/formats.md, point clouds): a
// uchar `camera` property and `comment camera <i> <name>` lines.
#include <cmath>

#include "formats/point_cloud.hpp"
#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;
using testing::readText;
using testing::throwsInputError;
using testing::writeText;

PointCloud cameraCloud(float x0, std::size_t n) {
  PointCloud cloud;
  cloud.property_names = {"intensity", "u", "v"};
  cloud.properties.assign(3, {});
  for (std::size_t i = 0; i < n; ++i) {
    cloud.xyz.insert(cloud.xyz.end(), {x0 + static_cast<float>(i), 1.0f, 500.0f});
    for (auto& p : cloud.properties)
      p.push_back(static_cast<float>(i) + 0.5f);
  }
  return cloud;
}

class MergedCloudTest : public testing::TempDirTest {
 protected:
  fs::path file() const { return dir_ / "merged.ply"; }
};

TEST_F(MergedCloudTest, CamerasRoundTripAsUcharWithTheirNames) {
  PointCloud merged;
  appendCameraCloud(merged, cameraCloud(0.0f, 3), 0, "main");
  appendCameraCloud(merged, cameraCloud(100.0f, 2), 1, "cam90");
  ASSERT_EQ(merged.size(), 5u);
  writePly(file(), merged);
  const std::string text = readText(file());
  EXPECT_NE(text.find("comment camera 0 main\ncomment camera 1 cam90\n"), std::string::npos);
  EXPECT_NE(text.find("property uchar camera\n"), std::string::npos);
  // 5 points of 6 floats and one byte after the header.
  EXPECT_EQ(text.size() - (text.find("end_header\n") + 11), 5u * (6 * 4 + 1));

  const PointCloud back = readPly(file());
  EXPECT_EQ(cameraNamesOf(back), (std::vector<std::string>{"main", "cam90"}));
  ASSERT_EQ(back.property_names.back(), "camera");
  EXPECT_EQ(back.properties.back(), (std::vector<float>{0, 0, 0, 1, 1}));
  EXPECT_EQ(back.property_types.back(), PlyScalar::UInt8);
  EXPECT_EQ(back.xyz[9], 100.0f);
  EXPECT_EQ(back.properties[0][3], 0.5f);
}

TEST_F(MergedCloudTest, UcharValuesMustBeBytes) {
  PointCloud merged;
  appendCameraCloud(merged, cameraCloud(0.0f, 2), 0, "main");
  merged.properties.back()[1] = 256.0f;
  EXPECT_THROW(writePly(file(), merged), std::invalid_argument);
  merged.properties.back()[1] = 1.5f;
  EXPECT_THROW(writePly(file(), merged), std::invalid_argument);
}

TEST_F(MergedCloudTest, CamerasWithOtherPropertiesAreNotMerged) {
  PointCloud merged;
  appendCameraCloud(merged, cameraCloud(0.0f, 2), 0, "main");
  PointCloud other = cameraCloud(0.0f, 2);
  other.property_names[0] = "quality";
  EXPECT_THROW(appendCameraCloud(merged, other, 1, "cam90"), std::invalid_argument);
  EXPECT_THROW(appendCameraCloud(merged, cameraCloud(0.0f, 2), 1, "cam 90"), std::invalid_argument);
}

TEST_F(MergedCloudTest, AMalformedCameraCommentIsRefused) {
  const auto with = [](const std::string& comment) {
    return "ply\nformat ascii 1.0\n" + comment +
           "\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  };
  writeText(file(), with("comment camera 300 main"));
  EXPECT_TRUE(throwsInputError([&] { readPly(file()); }, file(), {"camera index"}));
  writeText(file(), with("comment camera 1 two words"));
  EXPECT_TRUE(
      throwsInputError([&] { readPly(file()); }, file(), {"comment camera <index> <name>"}));
  // Another program's camera comment is an ordinary one.
  writeText(file(), with("comment camera model XYZ-100"));
  const PointCloud cloud = readPly(file());
  EXPECT_EQ(cloud.comments, (std::vector<std::string>{"camera model XYZ-100"}));
  EXPECT_TRUE(cameraNamesOf(cloud).empty());
}

TEST_F(MergedCloudTest, OtherCommentsAreKept) {
  writeText(file(),
            "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 1\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n1 2 3\n");
  const PointCloud cloud = readPly(file());
  EXPECT_EQ(cloud.comments, (std::vector<std::string>{"made by hand"}));
  EXPECT_TRUE(cameraNamesOf(cloud).empty());
}

}  // namespace
}  // namespace cylscan::formats
