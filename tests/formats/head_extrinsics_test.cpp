// SPDX-License-Identifier: Apache-2.0
#include "formats/head_extrinsics.hpp"

#include "common/vocabulary.hpp"

#include <cmath>

#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;
using testing::throwsInputError;
using testing::writeText;

HeadExtrinsics sampleHead() {
  HeadExtrinsics head;
  head.cameras["main"] = CameraPose{};
  CameraPose cam90;  // 90° about y, then shifted
  cam90.R = {{{0, 0, 1}, {0, 1, 0}, {-1, 0, 0}}};
  cam90.T = {120.25, -0.5, 119.75};
  head.cameras["cam90"] = cam90;
  head.rms_mm = 0.0125;
  head.turntable_axis = AxisRecord{{118.0, 0.0, 2.0}, {0.0, -1.0, 0.0}};
  head.extra["residuals"] = {{"cam90", {{"rms_mm", 0.01}}}};
  return head;
}

class HeadExtrinsicsTest : public testing::TempDirTest {
 protected:
  fs::path file() const { return dir_ / "head.json"; }

  ::testing::AssertionResult readFails(std::string_view text,
                                       std::initializer_list<std::string_view> needles) {
    writeText(file(), text);
    return throwsInputError([&] { readHeadExtrinsics(file()); }, file(), needles);
  }

  static std::string withCam90(const std::string& cam90) {
    return R"({"format": "cylscan-head-1", "frame": "main", "cameras": {"main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]}, "cam90": )" +
           cam90 + "}}";
  }
};

TEST_F(HeadExtrinsicsTest, RoundTripKeepsEveryField) {
  const HeadExtrinsics head = sampleHead();
  writeHeadExtrinsics(file(), head);
  const HeadExtrinsics back = readHeadExtrinsics(file());
  EXPECT_EQ(back.frame, "main");
  EXPECT_EQ(back.method, "turntable");
  ASSERT_EQ(back.cameras.size(), 2u);
  EXPECT_EQ(back.pose("cam90").R, head.pose("cam90").R);
  EXPECT_EQ(back.pose("cam90").T, head.pose("cam90").T);  // doubles written exactly
  EXPECT_EQ(back.rms_mm, 0.0125);
  ASSERT_TRUE(back.turntable_axis);
  EXPECT_EQ(back.turntable_axis->point[0], 118.0);
  EXPECT_EQ(back.extra["residuals"]["cam90"]["rms_mm"], 0.01);
  const std::array<double, 3> x = back.pose("cam90").apply({1.0, 2.0, 3.0});
  EXPECT_DOUBLE_EQ(x[0], 123.25);
  EXPECT_DOUBLE_EQ(x[2], 118.75);
}

TEST_F(HeadExtrinsicsTest, TheFormatIsRequired) {
  EXPECT_TRUE(readFails(R"({"cameras": {}})", {"\"format\"", "cylscan-head-1"}));
  EXPECT_TRUE(readFails("{not json", {"not valid JSON"}));
}

TEST_F(HeadExtrinsicsTest, TheFrameCameraMustBePresentAndTheIdentity) {
  EXPECT_TRUE(readFails(
      R"({"format": "cylscan-head-1", "frame": "main", "cameras": {"cam90": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]}}})",
      {"\"frame\"", "'main'", "not in \"cameras\""}));
  EXPECT_TRUE(readFails(
      R"({"format": "cylscan-head-1", "cameras": {"main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [1,0,0]}}})",
      {"cameras.main", "identity"}));
}

TEST_F(HeadExtrinsicsTest, EachPoseIsValidatedNamingTheField) {
  EXPECT_TRUE(
      readFails(withCam90(R"({"R": [[1,0,0],[0,1,0],[0,0,1]]})"), {"cameras.cam90", "\"T\""}));
  EXPECT_TRUE(
      readFails(withCam90(R"({"R": [[1,0,0],[0,1,0]], "T": [0,0,0]})"), {"cameras.cam90.R"}));
  EXPECT_TRUE(readFails(withCam90(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,"a",0]})"),
                        {"cameras.cam90.T[1]", "number"}));
  EXPECT_TRUE(readFails(withCam90(R"({"R": [[1,0,0],[0,1.1,0],[0,0,1]], "T": [0,0,0]})"),
                        {"cameras.cam90.R", "not a rotation"}));
  EXPECT_TRUE(readFails(withCam90(R"({"R": [[1,0,0],[0,1,0],[0,0,-1]], "T": [0,0,0]})"),
                        {"cameras.cam90.R", "reflection"}));
  EXPECT_TRUE(readFails(withCam90(R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,1e9]})"),
                        {"cameras.cam90.T", "100 m"}));
}

TEST_F(HeadExtrinsicsTest, CameraNamesAreChecked) {
  EXPECT_TRUE(readFails(
      R"({"format": "cylscan-head-1", "cameras": {"main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]}, "../x": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]}}})",
      {"cameras.../x", "not a camera name"}));
  EXPECT_TRUE(isCameraName("cam_90-b"));
  EXPECT_FALSE(isCameraName(""));
  EXPECT_FALSE(isCameraName("a b"));
  // One rule with the board profile's: lower case, at most 32, no leading _ or -.
  EXPECT_FALSE(isCameraName("Main"));
  EXPECT_FALSE(isCameraName("_main"));
  EXPECT_TRUE(isCameraName(std::string(32, 'c')));
  EXPECT_FALSE(isCameraName(std::string(33, 'c')));
}

TEST_F(HeadExtrinsicsTest, TheAxisDirectionIsAUnitVector) {
  EXPECT_TRUE(readFails(
      R"({"format": "cylscan-head-1", "cameras": {"main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]}}, "turntable_axis": {"point": [0,0,0], "direction": [0,2,0]}})",
      {"turntable_axis.direction", "unit"}));
}

TEST_F(HeadExtrinsicsTest, ParsingTextNamesTheSource) {
  EXPECT_TRUE(throwsInputError([] { parseHeadExtrinsics("[]", "PUT /api/v1/head"); },
                               "PUT /api/v1/head", {"JSON object"}));
}

TEST_F(HeadExtrinsicsTest, WritingAnInvalidHeadIsRefused) {
  HeadExtrinsics head;  // no cameras
  EXPECT_THROW(writeHeadExtrinsics(file(), head), std::invalid_argument);
  EXPECT_FALSE(fs::exists(file()));
}

}  // namespace
}  // namespace cylscan::formats
