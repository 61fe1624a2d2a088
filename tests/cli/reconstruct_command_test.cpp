// SPDX-License-Identifier: Apache-2.0
// `cylscan reconstruct`: the quasi path on a synthetic bundle with a known
// calibration, the PLY and depth outputs, and every bad-input path.
#include <cmath>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "algo/quasi_calibration.hpp"
#include "cli_support.hpp"
#include "formats/atomic_file.hpp"
#include "formats/images.hpp"
#include "formats/point_cloud.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The model every pixel of the test calibration has: X = u, Y = v, Z = 500 + 2Φ.
constexpr double kZ0 = 500.0, kZPerRad = 2.0;

// A calibration of `size` fitted from 8 poses around `phase` (or around 20 rad
// when phase is empty), with the exact targets of the model above.
void writeCalibration(const fs::path& file, cv::Size size, const cv::Mat& phase = cv::Mat(),
                      PhaseSource source = PhaseSource::Fused) {
  algo::QuasiCalibrationOptions options;
  options.phase_source = source;
  algo::QuasiCalibrationFitter fitter(size, options);
  for (int k = 0; k < 8; ++k) {
    cv::Mat pose_phase(size, CV_32F);
    cv::Mat target(size, CV_32FC3);
    for (int v = 0; v < size.height; ++v) {
      for (int u = 0; u < size.width; ++u) {
        const double centre = phase.empty() ? 20.0 : phase.at<double>(v, u);
        const double phi = centre + (k - 3.5) * 0.5;
        pose_phase.at<float>(v, u) = static_cast<float>(phi);
        target.at<cv::Vec3f>(v, u) = cv::Vec3f(static_cast<float>(u), static_cast<float>(v),
                                               static_cast<float>(kZ0 + kZPerRad * phi));
      }
    }
    fitter.addPose(pose_phase, target);
  }
  formats::writeFileAtomically(file, fitter.fit().serialize());
}

formats::StereoCalibration stereoFor(cv::Size size) {
  formats::StereoCalibration c;
  c.image_width = size.width;
  c.image_height = size.height;
  c.camera_matrix_main = cv::Matx33d(300, 0, size.width / 2.0, 0, 300, size.height / 2.0, 0, 0, 1);
  c.dist_coeffs_main = cv::Vec<double, 5>::all(0.0);
  c.camera_matrix_aux = c.camera_matrix_main;
  c.dist_coeffs_aux = c.dist_coeffs_main;
  c.R = cv::Matx33d::eye();
  c.T = cv::Vec3d(-100, 0, 0);
  return c;
}

int propertyIndex(const formats::PointCloud& cloud, const std::string& name) {
  for (std::size_t i = 0; i < cloud.property_names.size(); ++i) {
    if (cloud.property_names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

class ReconstructCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    truth_ = writeSyntheticBundle(bundle(), size_, 12, {"main", "aux"});
    writeSyntheticBundle(mainOnly(), size_, 4);
  }
  fs::path bundle() const { return tmp_.path() / "bundle"; }
  fs::path mainOnly() const { return tmp_.path() / "main_only"; }
  fs::path path(const std::string& name) const { return tmp_.path() / name; }
  std::string out() const { return " --out " + path("cloud.ply").string() + " "; }

  TempDir tmp_;
  cv::Size size_{96, 64};
  SyntheticBundle truth_;
};

TEST_F(ReconstructCommand, QuasiWritesThePlyWithIntensityAndPixelsAndTheDepthMap) {
  writeCalibration(path("calib.qcal"), size_, truth_.absolute);
  const auto run = runTool("reconstruct --json --calib " + path("calib.qcal").string() + out() +
                           "--depth " + path("depth.tiff").string() + " " + bundle().string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const json summary = json::parse(run.output);
  EXPECT_EQ(summary.at("method"), "quasi");
  EXPECT_EQ(summary.at("phase"), "fused");  // the calibration's
  EXPECT_GT(summary.at("point_fraction").get<double>(), 0.99);

  const formats::PointCloud cloud = formats::readPly(path("cloud.ply"));
  EXPECT_EQ(static_cast<int>(cloud.size()), summary.at("points").get<int>());
  const int iu = propertyIndex(cloud, "u"), iv = propertyIndex(cloud, "v");
  const int ii = propertyIndex(cloud, "intensity");
  ASSERT_GE(iu, 0);
  ASSERT_GE(iv, 0);
  ASSERT_GE(ii, 0);
  const cv::Mat depth = formats::readFloatTiff(path("depth.tiff"));
  ASSERT_EQ(depth.size(), size_);
  double worst = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const float u = cloud.properties[static_cast<std::size_t>(iu)][i];
    const float v = cloud.properties[static_cast<std::size_t>(iv)][i];
    const int ui = static_cast<int>(u), vi = static_cast<int>(v);
    ASSERT_NEAR(cloud.xyz[3 * i], u, 1e-3);  // X = u and Y = v (constant polynomials)
    ASSERT_NEAR(cloud.xyz[3 * i + 1], v, 1e-3);
    const double z_truth = kZ0 + kZPerRad * truth_.absolute.at<double>(vi, ui);
    worst = std::max(worst, std::abs(cloud.xyz[3 * i + 2] - z_truth));
    ASSERT_EQ(depth.at<float>(vi, ui), cloud.xyz[3 * i + 2]);
    ASSERT_NEAR(cloud.properties[static_cast<std::size_t>(ii)][i], 120.0, 2.0);
  }
  EXPECT_LT(worst, 2.0 * 0.02);  // the phase is good to 0.02 rad (phase test)
  const int invalid = static_cast<int>(depth.total()) - cv::countNonZero(depth == depth);
  EXPECT_EQ(invalid, size_.area() - static_cast<int>(cloud.size()));  // NaN where no point
}

TEST_F(ReconstructCommand, PhaseOtherThanTheCalibrationsIsBadInputNamingCalib) {
  writeCalibration(path("calib.qcal"), size_, truth_.absolute);
  const auto run = runTool("reconstruct --phase high --calib " + path("calib.qcal").string() +
                           out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("calib.qcal"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("fused"), std::string::npos) << run.output;
}

TEST_F(ReconstructCommand, MissingCalibIsBadInputNamingIt) {
  const auto run =
      runTool("reconstruct --calib " + path("nowhere.qcal").string() + out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("nowhere.qcal"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("cloud.ply")));
}

TEST_F(ReconstructCommand, CorruptCalibIsBadInputNamingTheFileAndFault) {
  writeCalibration(path("calib.qcal"), size_);
  std::fstream file(path("calib.qcal"), std::ios::in | std::ios::out | std::ios::binary);
  file.seekp(5000);
  file.put('\x5a');
  file.close();
  const auto run =
      runTool("reconstruct --calib " + path("calib.qcal").string() + out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("calib.qcal"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("checksum"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("cloud.ply")));
}

TEST_F(ReconstructCommand, TruncatedOrForeignCalibIsBadInput) {
  writeCalibration(path("calib.qcal"), size_);
  fs::resize_file(path("calib.qcal"), fs::file_size(path("calib.qcal")) / 2);
  auto run =
      runTool("reconstruct --calib " + path("calib.qcal").string() + out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("truncated"), std::string::npos) << run.output;

  std::ofstream(path("text.qcal")) << "just some text, not a calibration at all, really not";
  run = runTool("reconstruct --calib " + path("text.qcal").string() + out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("text.qcal"), std::string::npos) << run.output;
}

TEST_F(ReconstructCommand, CalibForAnotherImageSizeIsBadInputNamingCalib) {
  writeCalibration(path("small.qcal"), {8, 6});
  const auto run =
      runTool("reconstruct --calib " + path("small.qcal").string() + out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("small.qcal"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("8x6"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("96x64"), std::string::npos) << run.output;
}

TEST_F(ReconstructCommand, WrongMethodCombinationsAreBadInput) {
  writeCalibration(path("calib.qcal"), size_);
  formats::writeStereoCalibration(path("stereo.yaml"), stereoFor(size_));
  const std::string calib = " --calib " + path("calib.qcal").string();
  const std::string stereo = " --stereo " + path("stereo.yaml").string();
  const std::string b = " " + bundle().string();
  for (const std::string& args :
       {"reconstruct" + out() + b,                                   // quasi without --calib
        "reconstruct" + calib + stereo + out() + b,                  // quasi with --stereo
        "reconstruct --method stereo" + out() + b,                   // stereo without --stereo
        "reconstruct --method stereo" + stereo + calib + out() + b,  // stereo with --calib
        "reconstruct --method stereo" + calib + out() + b,
        "reconstruct --method magic" + calib + out() + b}) {
    const auto run = runTool(args);
    EXPECT_EQ(run.exit_code, 2) << args << "\n" << run.output;
  }
  EXPECT_FALSE(fs::exists(path("cloud.ply")));
}

TEST_F(ReconstructCommand, StereoGarbageIsBadInputNamingTheFile) {
  std::ofstream(path("stereo.yaml")) << "%YAML:1.0\n---\nimage_width: [ this is : not valid\n";
  const auto run = runTool("reconstruct --method stereo --stereo " + path("stereo.yaml").string() +
                           out() + bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("stereo.yaml"), std::string::npos) << run.output;
}

TEST_F(ReconstructCommand, StereoNeedsAnAuxCameraAndTheCalibratedSize) {
  formats::writeStereoCalibration(path("stereo.yaml"), stereoFor(size_));
  auto run = runTool("reconstruct --method stereo --stereo " + path("stereo.yaml").string() +
                     out() + mainOnly().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("main_only"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("aux"), std::string::npos) << run.output;

  formats::writeStereoCalibration(path("other.yaml"), stereoFor({640, 480}));
  run = runTool("reconstruct --method stereo --stereo " + path("other.yaml").string() + out() +
                bundle().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("other.yaml"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("640x480"), std::string::npos) << run.output;
}

// The one-set extension is `cylscan phase`'s alone: reconstruct needs the
// absolute phase and refuses the bundle as the contract says.
TEST_F(ReconstructCommand, OneSetBundleIsBadInputNamingCaptureJson) {
  writeCalibration(path("calib.qcal"), size_, truth_.absolute);
  removeFringeSet(mainOnly(), FringeSet::Low);
  const auto run =
      runTool("reconstruct --calib " + path("calib.qcal").string() + out() + mainOnly().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find((mainOnly() / "capture.json").string()), std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("missing set \"low\""), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("cloud.ply")));
}

TEST_F(ReconstructCommand, MissingBundleIsBadInput) {
  writeCalibration(path("calib.qcal"), size_);
  const auto run = runTool("reconstruct --calib " + path("calib.qcal").string() + out() +
                           path("nowhere").string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("nowhere"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace cylscan::test
