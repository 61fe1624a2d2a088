// SPDX-License-Identifier: Apache-2.0
// `cylscan evaluate plane|sphere` on clouds with a known surface and noise.
#include <cmath>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

json runJson(const std::string& args) {
  const auto run = runTool(args + " --json");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  return json::parse(run.output);
}

// A plane z = 600 + 0.1·x − 0.05·y seen on a width × height grid of pixels
// (x = u − 160, y = v − 128 mm), with Gaussian noise of `sigma` along the
// normal; the right third of the image (u ≥ 2/3·width) has `outer_sigma`.
formats::PointCloud planeCloud(int width, int height, double sigma, double outer_sigma,
                               unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double a = 0.1, b = -0.05;
  const double norm = std::sqrt(a * a + b * b + 1.0);
  const double n[3] = {-a / norm, -b / norm, 1.0 / norm};
  formats::PointCloud cloud;
  cloud.property_names = {"intensity", "u", "v"};
  cloud.properties.resize(3);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const double x = u - 160.0, y = v - 128.0;
      const double z = 600.0 + a * x + b * y;
      const double s = u >= 2 * width / 3 ? outer_sigma : sigma;
      const double e = s * unit(rng);
      cloud.xyz.insert(cloud.xyz.end(),
                       {static_cast<float>(x + e * n[0]), static_cast<float>(y + e * n[1]),
                        static_cast<float>(z + e * n[2])});
      cloud.properties[0].push_back(100.0f);
      cloud.properties[1].push_back(static_cast<float>(u));
      cloud.properties[2].push_back(static_cast<float>(v));
    }
  }
  return cloud;
}

// The visible cap (the half facing the camera at the origin) of a sphere,
// with radial noise `sigma` and a radial bias `bias`.
formats::PointCloud sphereCloud(const double centre[3], double radius, double sigma, double bias,
                                unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  formats::PointCloud cloud;
  for (int i = 0; i < 120; ++i) {
    const double polar = 0.5 * kPi * i / 120.0;  // from the direction towards the camera
    for (int j = 0; j < 240; ++j) {
      const double azimuth = 2.0 * kPi * j / 240.0;
      const double d[3] = {std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth),
                           -std::cos(polar)};
      const double r = radius + bias + sigma * unit(rng);
      for (int k = 0; k < 3; ++k)
        cloud.xyz.push_back(static_cast<float>(centre[k] + r * d[k]));
    }
  }
  return cloud;
}

TEST(EvaluateCommand, PlaneRmseAndRegionsMatchTheNoise) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "plane.ply";
  formats::writePly(ply, planeCloud(320, 256, 0.05, 0.15, 7));
  const json out = runJson("evaluate plane " + ply.string());
  EXPECT_EQ(out.at("points").get<int>(), 320 * 256);
  // Central 30 % of u: σ = 0.05; outer 15 % bands: the left has 0.05, the right 0.15.
  const double outer = std::sqrt((0.05 * 0.05 + 0.15 * 0.15) / 2.0);
  const double total = std::sqrt((2.0 * 0.05 * 0.05 + 0.15 * 0.15) / 3.0);
  EXPECT_NEAR(out.at("rmse_mm").get<double>(), total, 0.03 * total);
  EXPECT_NEAR(out.at("regional").at("central_rmse_mm").get<double>(), 0.05, 0.002);
  EXPECT_NEAR(out.at("regional").at("outer_rmse_mm").get<double>(), outer, 0.03 * outer);
  const auto normal = out.at("plane").at("normal");
  const double nz = normal[2].get<double>();
  EXPECT_NEAR(nz, 1.0 / std::sqrt(0.01 + 0.0025 + 1.0), 1e-4);
}

TEST(EvaluateCommand, PlaneTextOutputHasThreeDecimalsInMm) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "plane.ply";
  formats::writePly(ply, planeCloud(64, 48, 0.1, 0.1, 3));
  const auto run = runTool("evaluate plane " + ply.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("RMSE 0.1"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find(" mm"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("central 30 %"), std::string::npos) << run.output;
}

TEST(EvaluateCommand, PlaneWithoutUHasNoRegions) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "plane.ply";
  formats::PointCloud cloud = planeCloud(40, 30, 0.02, 0.02, 5);
  cloud.property_names.clear();
  cloud.properties.clear();
  formats::writePly(ply, cloud);
  const json out = runJson("evaluate plane " + ply.string());
  EXPECT_FALSE(out.contains("regional"));
  EXPECT_NEAR(out.at("rmse_mm").get<double>(), 0.02, 0.002);
}

TEST(EvaluateCommand, SphereFreeAndFixedRadiusFits) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "sphere.ply";
  const double centre[3] = {10.0, -5.0, 580.0};
  // A sphere of radius 50.2 measured as such: the free fit finds 50.2. The
  // reference sphere of R = 50 fitted by its centre moves towards the cap and
  // absorbs most of the 0.2 mm: with these samples (uniform in the polar angle
  // θ) the signed mean left is 0.2·(1 − <cos θ>²/<cos² θ>) ≈ 0.038 mm.
  formats::writePly(ply, sphereCloud(centre, 50.2, 0.1, 0.0, 11));
  const json out = runJson("evaluate sphere --radius 50 " + ply.string());
  EXPECT_EQ(out.at("points").get<int>(), 120 * 240);
  EXPECT_NEAR(out.at("free").at("radius_mm").get<double>(), 50.2, 0.01);
  EXPECT_NEAR(out.at("free").at("rmse_mm").get<double>(), 0.1, 0.003);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(out.at("free").at("centre")[k].get<double>(), centre[k], 0.02) << k;
  }
  const json ref = out.at("reference");
  EXPECT_EQ(ref.at("radius_mm").get<double>(), 50.0);
  const double mean = ref.at("mean_mm").get<double>();
  const double std = ref.at("std_mm").get<double>();
  EXPECT_NEAR(mean, 0.2 * (1.0 - (4.0 / (kPi * kPi)) / 0.5), 0.01);
  EXPECT_NEAR(ref.at("rmse_mm").get<double>(), std::sqrt(mean * mean + std * std), 1e-9);
  EXPECT_GT(std, 0.099);
}

TEST(EvaluateCommand, SphereOfTheRightRadiusHasNoBias) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "sphere.ply";
  const double centre[3] = {-20.0, 15.0, 560.0};
  formats::writePly(ply, sphereCloud(centre, 50.0, 0.3, 0.0, 13));
  const json out = runJson("evaluate sphere --radius 50 " + ply.string());
  EXPECT_NEAR(out.at("free").at("radius_mm").get<double>(), 50.0, 0.03);
  EXPECT_NEAR(out.at("reference").at("mean_mm").get<double>(), 0.0, 0.01);
  EXPECT_NEAR(out.at("reference").at("rmse_mm").get<double>(), 0.3, 0.01);
}

TEST(EvaluateCommand, NonFiniteVerticesAreDropped) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "plane.ply";
  formats::PointCloud cloud = planeCloud(40, 30, 0.02, 0.02, 5);
  cloud.xyz[0] = std::numeric_limits<float>::quiet_NaN();
  cloud.xyz[5] = std::numeric_limits<float>::infinity();
  formats::writePly(ply, cloud);
  const json out = runJson("evaluate plane " + ply.string());
  EXPECT_EQ(out.at("points").get<int>(), 40 * 30 - 2);
  EXPECT_EQ(out.at("dropped_points").get<int>(), 2);
  EXPECT_NEAR(out.at("rmse_mm").get<double>(), 0.02, 0.002);
}

TEST(EvaluateCommand, EmptyCloudIsBadInputNamingTheFile) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "empty.ply";
  formats::writePly(ply, formats::PointCloud{});
  for (const std::string& shape : {std::string("plane"), std::string("sphere --radius 50")}) {
    const auto run = runTool("evaluate " + shape + " " + ply.string());
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_NE(run.output.find("empty.ply"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("0 finite points"), std::string::npos) << run.output;
  }
}

TEST(EvaluateCommand, DegenerateCloudIsBadInput) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "line.ply";
  formats::PointCloud cloud;
  for (int i = 0; i < 50; ++i)
    cloud.xyz.insert(cloud.xyz.end(), {1.0f * i, 2.0f * i, 500.0f});
  formats::writePly(ply, cloud);
  const auto run = runTool("evaluate plane " + ply.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("line.ply"), std::string::npos) << run.output;
}

TEST(EvaluateCommand, MissingOrCorruptCloudIsBadInputNamingTheFile) {
  TempDir tmp;
  const auto missing = runTool("evaluate plane " + (tmp.path() / "nowhere.ply").string());
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("nowhere.ply"), std::string::npos) << missing.output;

  const fs::path garbage = tmp.path() / "garbage.ply";
  std::ofstream(garbage, std::ios::binary) << "this is not a ply file\n";
  const auto bad = runTool("evaluate sphere --radius 50 " + garbage.string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("garbage.ply"), std::string::npos) << bad.output;
}

TEST(EvaluateCommand, UsageErrors) {
  TempDir tmp;
  const fs::path ply = tmp.path() / "plane.ply";
  formats::writePly(ply, planeCloud(20, 20, 0.02, 0.02, 5));
  EXPECT_EQ(runTool("evaluate " + ply.string()).exit_code, 2);         // no shape
  EXPECT_EQ(runTool("evaluate sphere " + ply.string()).exit_code, 2);  // no --radius
  EXPECT_EQ(runTool("evaluate sphere --radius -3 " + ply.string()).exit_code, 2);
}

}  // namespace
}  // namespace cylscan::test
