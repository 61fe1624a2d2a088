// SPDX-License-Identifier: Apache-2.0
#include "formats/stereo_calibration.hpp"

#include <cmath>
#include <limits>
#include <map>

#include "tests/formats/test_support.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

using testing::readText;
using testing::throwsInputError;
using testing::writeText;

StereoCalibration sampleCalibration() {
  StereoCalibration c;
  c.image_width = 1280;
  c.image_height = 1024;
  c.camera_matrix_main = cv::Matx33d(2400.5, 0, 640.25, 0, 2401.75, 511.5, 0, 0, 1);
  c.dist_coeffs_main = cv::Vec<double, 5>(-0.1, 0.05, 1e-4, -2e-4, 0.001);
  c.camera_matrix_aux = cv::Matx33d(2390, 0.5, 630, 0, 2391, 500, 0, 0, 1);
  c.dist_coeffs_aux = cv::Vec<double, 5>(-0.09, 0.04, 0, 0, 0);
  const double a = -0.35;  // about y, then a little about z
  const double b = 0.02;
  const cv::Matx33d ry(std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a));
  const cv::Matx33d rz(std::cos(b), -std::sin(b), 0, std::sin(b), std::cos(b), 0, 0, 0, 1);
  c.R = rz * ry;
  c.T = cv::Vec3d(-150.5, 1.25, 30.0);
  return c;
}

std::string matrixText(int rows, int cols, const std::string& data) {
  return "!!opencv-matrix\n   rows: " + std::to_string(rows) +
         "\n   cols: " + std::to_string(cols) + "\n   dt: d\n   data: [ " + data + " ]";
}

// The nodes of a valid file as YAML texts; tests replace or erase some.
std::map<std::string, std::string> validNodes() {
  return {
      {"image_width", "1280"},
      {"image_height", "1024"},
      {"camera_matrix_main", matrixText(3, 3, "2400., 0., 640., 0., 2400., 512., 0., 0., 1.")},
      {"dist_coeffs_main", matrixText(1, 5, "-0.1, 0.05, 0., 0., 0.")},
      {"camera_matrix_aux", matrixText(3, 3, "2390., 0., 630., 0., 2390., 500., 0., 0., 1.")},
      {"dist_coeffs_aux", matrixText(1, 5, "-0.1, 0.05, 0., 0., 0.")},
      {"R", matrixText(3, 3, "0., 0., 1., 0., 1., 0., -1., 0., 0.")},
      {"T", matrixText(3, 1, "-150., 0., 30.")},
  };
}

std::string yaml(const std::map<std::string, std::string>& nodes) {
  std::string text = "%YAML:1.0\n---\n";
  for (const auto& [name, value] : nodes)
    text += name + ": " + value + "\n";
  return text;
}

class StereoCalibrationTest : public testing::TempDirTest {
 protected:
  fs::path file() const { return dir_ / "stereo.yaml"; }

  ::testing::AssertionResult readFails(const std::map<std::string, std::string>& nodes,
                                       std::initializer_list<std::string_view> needles) {
    writeText(file(), yaml(nodes));
    return throwsInputError([&] { readStereoCalibration(file()); }, file(), needles);
  }
};

TEST_F(StereoCalibrationTest, RoundTrip) {
  const StereoCalibration c = sampleCalibration();
  writeStereoCalibration(file(), c);
  const std::string text = readText(file());
  EXPECT_EQ(text.rfind("%YAML:1.0", 0), 0u);
  for (const char* node : {"image_width", "image_height", "camera_matrix_main", "dist_coeffs_main",
                           "camera_matrix_aux", "dist_coeffs_aux", "R:", "T:"}) {
    EXPECT_NE(text.find(node), std::string::npos) << node;
  }
  const StereoCalibration r = readStereoCalibration(file());
  EXPECT_EQ(r.image_width, 1280);
  EXPECT_EQ(r.image_height, 1024);
  EXPECT_EQ(cv::norm(r.camera_matrix_main, c.camera_matrix_main, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.camera_matrix_aux, c.camera_matrix_aux, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.dist_coeffs_main, c.dist_coeffs_main, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.dist_coeffs_aux, c.dist_coeffs_aux, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.R, c.R, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.T, c.T, cv::NORM_INF), 0);
}

TEST_F(StereoCalibrationTest, WritesTheShapesOfTheSpec) {
  writeStereoCalibration(file(), sampleCalibration());
  const cv::FileStorage fs(file().string(), cv::FileStorage::READ);
  cv::Mat dist;
  cv::Mat t;
  fs["dist_coeffs_main"] >> dist;
  fs["T"] >> t;
  EXPECT_EQ(dist.size(), cv::Size(5, 1));  // 1x5
  EXPECT_EQ(t.size(), cv::Size(1, 3));     // 3x1
}

TEST_F(StereoCalibrationTest, ReadsAHandWrittenFile) {
  writeText(file(), yaml(validNodes()));
  const StereoCalibration c = readStereoCalibration(file());
  EXPECT_EQ(c.camera_matrix_main(1, 2), 512.0);
  EXPECT_EQ(c.R(0, 2), 1.0);
  EXPECT_EQ(c.T[0], -150.0);
  EXPECT_EQ(c.dist_coeffs_aux[1], 0.05);
}

TEST_F(StereoCalibrationTest, AcceptsColumnDistortionVectors) {
  auto nodes = validNodes();
  nodes["dist_coeffs_main"] = matrixText(5, 1, "-0.1, 0.05, 0.001, 0.002, 0.003");
  writeText(file(), yaml(nodes));
  const StereoCalibration c = readStereoCalibration(file());
  EXPECT_EQ(c.dist_coeffs_main[4], 0.003);
  EXPECT_EQ(c.dist_coeffs_main[2], 0.001);
}

TEST_F(StereoCalibrationTest, MissingNode) {
  for (const char* node : {"image_width", "image_height", "camera_matrix_main", "dist_coeffs_main",
                           "camera_matrix_aux", "dist_coeffs_aux", "R", "T"}) {
    auto nodes = validNodes();
    nodes.erase(node);
    EXPECT_TRUE(readFails(nodes, {"node \"" + std::string(node) + "\" is missing"})) << node;
  }
}

TEST_F(StereoCalibrationTest, WrongMatrixSize) {
  auto nodes = validNodes();
  nodes["camera_matrix_aux"] = matrixText(2, 3, "1., 0., 0., 0., 1., 0.");
  EXPECT_TRUE(readFails(nodes, {"node \"camera_matrix_aux\"", "is 2x3, expected 3x3"}));
}

TEST_F(StereoCalibrationTest, WrongDistortionLength) {
  auto nodes = validNodes();
  nodes["dist_coeffs_aux"] = matrixText(1, 4, "0., 0., 0., 0.");
  EXPECT_TRUE(readFails(nodes, {"node \"dist_coeffs_aux\"", "is 1x4, expected 1x5"}));
}

TEST_F(StereoCalibrationTest, TranslationAsRowIsWrongSizeOnlyWhenNotThree) {
  auto nodes = validNodes();
  nodes["T"] = matrixText(2, 1, "1., 2.");
  EXPECT_TRUE(readFails(nodes, {"node \"T\"", "expected 3x1"}));
}

TEST_F(StereoCalibrationTest, NodeThatIsNotAMatrix) {
  auto nodes = validNodes();
  nodes["R"] = "\"identity\"";
  EXPECT_TRUE(readFails(nodes, {"node \"R\"", "not an OpenCV matrix"}));
}

TEST_F(StereoCalibrationTest, NonFiniteValue) {
  auto nodes = validNodes();
  nodes["T"] = matrixText(3, 1, "-150., .Nan, 30.");
  EXPECT_TRUE(readFails(nodes, {"node \"T\"", "not finite"}));
}

TEST_F(StereoCalibrationTest, InfiniteValueInCameraMatrix) {
  auto nodes = validNodes();
  nodes["camera_matrix_main"] = matrixText(3, 3, "2400., 0., .Inf, 0., 2400., 512., 0., 0., 1.");
  EXPECT_TRUE(readFails(nodes, {"node \"camera_matrix_main\"", "not finite"}));
}

TEST_F(StereoCalibrationTest, NonPositiveImageSize) {
  auto nodes = validNodes();
  nodes["image_height"] = "0";
  EXPECT_TRUE(readFails(nodes, {"node \"image_height\"", "must be > 0"}));
  nodes = validNodes();
  nodes["image_width"] = "-640";
  EXPECT_TRUE(readFails(nodes, {"node \"image_width\"", "must be > 0"}));
}

TEST_F(StereoCalibrationTest, ImageSizeNotAnInteger) {
  auto nodes = validNodes();
  nodes["image_width"] = "1280.5";
  EXPECT_TRUE(readFails(nodes, {"node \"image_width\"", "must be an integer"}));
}

TEST_F(StereoCalibrationTest, RotationThatIsNotOrthogonal) {
  auto nodes = validNodes();
  nodes["R"] = matrixText(3, 3, "1.001, 0., 0., 0., 1., 0., 0., 0., 1.");
  EXPECT_TRUE(readFails(nodes, {"node \"R\"", "not a rotation", "R^T R - I"}));
}

TEST_F(StereoCalibrationTest, ReflectionIsNotARotation) {
  auto nodes = validNodes();
  nodes["R"] = matrixText(3, 3, "1., 0., 0., 0., 1., 0., 0., 0., -1.");
  EXPECT_TRUE(readFails(nodes, {"node \"R\"", "determinant is -1"}));
}

TEST_F(StereoCalibrationTest, NonPositiveFocalLength) {
  auto nodes = validNodes();
  nodes["camera_matrix_aux"] = matrixText(3, 3, "2390., 0., 630., 0., -2390., 500., 0., 0., 1.");
  EXPECT_TRUE(readFails(nodes, {"node \"camera_matrix_aux\"", "focal lengths", "must be > 0"}));
}

TEST_F(StereoCalibrationTest, CameraMatrixWithWrongLastRow) {
  auto nodes = validNodes();
  nodes["camera_matrix_main"] = matrixText(3, 3, "2400., 0., 640., 0., 2400., 512., 0., 0., 2.");
  EXPECT_TRUE(readFails(nodes, {"node \"camera_matrix_main\"", "not a camera matrix"}));
}

TEST_F(StereoCalibrationTest, GarbageFile) {
  writeText(file(), "%YAML:1.0\n---\nR: [1, 2\n  : : {{{\n");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"not a valid OpenCV FileStorage"}));
}

// Found by fuzz/fuzz_stereo_yaml: OpenCV 4.6's YAML parser throws
// std::length_error (not cv::Exception) on this input; it is now refused by
// the line check before the parser sees it, and the reader also turns any
// std::exception of the parser into an InputError.
TEST_F(StereoCalibrationTest, IndentedFirstNodeIsRefused) {
  writeText(file(), "%YAML:1.\n r:3\n :");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"line 2", "first node must begin at the start"}));
}

// Found by fuzz/fuzz_stereo_yaml: OpenCV 4.6's YAML parser never returns on
// these inputs (after a top-level collection that ends early, a second
// document that starts with '-' but not "---"). The reader refuses them
// before OpenCV parses anything.
TEST_F(StereoCalibrationTest, InputsThatHangOpenCvAreRefusedBeforeParsing) {
  writeText(file(), "%YAML:1.0\n-----0\n----\nh");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"line 2", "document marker"}));
  writeText(file(), "%YAML:1.\n----h\nh\nh");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"line 2", "document marker"}));
  writeText(file(), yaml(validNodes()) + "...\n---\nR: 1\n");
  EXPECT_TRUE(
      throwsInputError([&] { readStereoCalibration(file()); }, file(), {"document end marker"}));
  writeText(file(), yaml(validNodes()) + "---\n");
  EXPECT_TRUE(
      throwsInputError([&] { readStereoCalibration(file()); }, file(), {"document marker"}));
  writeText(file(), yaml(validNodes()) + "1: 2\n");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"node name", "must begin every line"}));
}

TEST_F(StereoCalibrationTest, TopLevelIsAList) {
  writeText(file(), "%YAML:1.0\n---\n- 1\n- 2\n");
  EXPECT_TRUE(
      throwsInputError([&] { readStereoCalibration(file()); }, file(), {"top level is not a map"}));
}

TEST_F(StereoCalibrationTest, MatrixWithHugeRowCountIsRejectedBeforeAllocating) {
  auto nodes = validNodes();
  nodes["R"] = "!!opencv-matrix\n   rows: 300000000\n   cols: 300\n   dt: d\n   data: [ 1. ]";
  EXPECT_TRUE(readFails(nodes, {"node \"R\"", "is 300000000x300, expected 3x3"}));
}

TEST_F(StereoCalibrationTest, MatrixWithTooFewValues) {
  auto nodes = validNodes();
  nodes["R"] = matrixText(3, 3, "1., 0., 0., 0., 1., 0., 0., 0.");
  EXPECT_TRUE(readFails(nodes, {"node \"R\"", "has 8 values", "expected 9"}));
}

TEST_F(StereoCalibrationTest, BinaryGarbage) {
  writeText(file(), std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(), {}));
}

TEST_F(StereoCalibrationTest, EmptyFile) {
  writeText(file(), "");
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(), {"is empty"}));
}

TEST_F(StereoCalibrationTest, MissingFile) {
  EXPECT_TRUE(throwsInputError([&] { readStereoCalibration(file()); }, file(),
                               {"cannot open", "No such file"}));
}

TEST_F(StereoCalibrationTest, WriterRejectsAnInvalidCalibration) {
  StereoCalibration c = sampleCalibration();
  c.R(0, 0) = 2;
  EXPECT_THROW(writeStereoCalibration(file(), c), std::invalid_argument);
  c = sampleCalibration();
  c.image_width = 0;
  EXPECT_THROW(writeStereoCalibration(file(), c), std::invalid_argument);
  EXPECT_FALSE(fs::exists(file()));
}

TEST_F(StereoCalibrationTest, RejectedWriteKeepsTheOldFile) {
  writeStereoCalibration(file(), sampleCalibration());
  const std::string before = readText(file());
  StereoCalibration c = sampleCalibration();
  c.T[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(writeStereoCalibration(file(), c), std::invalid_argument);
  EXPECT_EQ(readText(file()), before);
  EXPECT_EQ(testing::entriesOf(dir_), std::vector<std::string>{"stereo.yaml"});
}

}  // namespace
}  // namespace cylscan::formats
