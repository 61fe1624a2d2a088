// SPDX-License-Identifier: Apache-2.0
#include "algo/quasi_calibration.hpp"

#include <cmath>
#include <cstring>
#include <iostream>
#include <numbers>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "algo/ray_plane.hpp"
#include "tests/calib/synthetic_scene.hpp"

namespace cylscan::algo {
namespace {

using ::testing::HasSubstr;
using testing::kNaNf;

// ------------------------------------------------------------- exact cubics

// Per pixel a random cubic Φ ↦ XYZ around Φ0 (in raw Φ, not normalised),
// sampled at `poses` phases over a range of about 2 rad.
struct CubicTruth {
  cv::Size size{24, 16};
  std::vector<std::array<double, 12>> coefficients;  // x0..x3, y0..y3, z0..z3 in (Φ − Φ0)
  std::vector<double> phi0;

  explicit CubicTruth(std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int i = 0; i < size.area(); ++i) {
      phi0.push_back(35.0 + 10.0 * unit(rng));
      std::array<double, 12> c{};
      for (int axis = 0; axis < 3; ++axis) {
        c[4 * axis + 0] = axis == 2 ? 580.0 + 20 * unit(rng) : 60.0 * unit(rng);
        c[4 * axis + 1] = (axis == 2 ? 39.0 : 5.0) * (1.0 + 0.2 * unit(rng));
        c[4 * axis + 2] = 0.8 * unit(rng);
        c[4 * axis + 3] = 0.1 * unit(rng);
      }
      coefficients.push_back(c);
    }
  }
  cv::Vec3d at(int i, double phi) const {
    const double s = phi - phi0[static_cast<std::size_t>(i)];
    const auto& c = coefficients[static_cast<std::size_t>(i)];
    cv::Vec3d out;
    for (int axis = 0; axis < 3; ++axis)
      out[axis] = c[4 * axis] + s * (c[4 * axis + 1] + s * (c[4 * axis + 2] + s * c[4 * axis + 3]));
    return out;
  }
  // Pose j of `poses`: each pixel at its own phase spread over [Φ0 − 1, Φ0 + 1.2].
  void pose(int j, int poses, cv::Mat& phase, cv::Mat& xyz) const {
    phase.create(size, CV_32FC1);
    xyz.create(size, CV_32FC3);
    for (int i = 0; i < size.area(); ++i) {
      const double frac = (j + 0.37 * std::sin(1.7 * i + j)) / (poses - 1);
      const float phi = static_cast<float>(phi0[static_cast<std::size_t>(i)] - 1.0 + 2.2 * frac);
      phase.at<float>(i / size.width, i % size.width) = phi;
      const cv::Vec3d p = at(i, phi);
      xyz.at<cv::Vec3f>(i / size.width, i % size.width) =
          cv::Vec3f(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
    }
  }
};

TEST(QuasiCalibration, RecoversExactCubicsToFloatPrecision) {
  const CubicTruth truth(11);
  QuasiCalibrationFitter fitter(truth.size);
  const int poses = 10;
  cv::Mat phase, xyz;
  for (int j = 0; j < poses; ++j) {
    truth.pose(j, poses, phase, xyz);
    fitter.addPose(phase, xyz);
  }
  const QuasiCalibration calibration = fitter.fit();
  ASSERT_EQ(calibration.validCount(), static_cast<std::size_t>(truth.size.area()));
  double worst = 0.0;
  for (int i = 0; i < truth.size.area(); ++i) {
    const int u = i % truth.size.width;
    const int v = i / truth.size.width;
    for (double s = -0.9; s <= 1.1; s += 0.05) {
      const float phi = static_cast<float>(truth.phi0[static_cast<std::size_t>(i)] + s);
      const cv::Vec3f p = calibration.evaluate(u, v, phi);
      const cv::Vec3d t = truth.at(i, phi);
      for (int a = 0; a < 3; ++a)
        worst = std::max(worst, std::abs(p[a] - t[a]));
    }
  }
  // Targets and coefficients are float32: |Z| ≈ 600 mm has an ulp of 6e-5 mm;
  // a few ulps of rounding in the Horner steps and in the targets.
  EXPECT_LT(worst, 3e-4) << "worst coordinate error " << worst << " mm";
  std::cout << "exact cubics: worst coordinate error " << worst << " mm\n";
  RecordProperty("exact_cubic_worst_mm", std::to_string(worst));
}

TEST(QuasiCalibration, PixelsWithTooFewPosesAreInvalid) {
  const CubicTruth truth(12);
  QuasiCalibrationFitter fitter(truth.size);  // min_poses = 6
  cv::Mat phase, xyz;
  for (int j = 0; j < 8; ++j) {
    truth.pose(j, 8, phase, xyz);
    if (j >= 5) phase.at<float>(2, 3) = kNaNf;       // pixel (3, 2): 5 poses
    if (j >= 6) xyz.at<cv::Vec3f>(4, 5)[1] = kNaNf;  // pixel (5, 4): 6 poses
    fitter.addPose(phase, xyz);
  }
  const QuasiCalibration calibration = fitter.fit();
  EXPECT_FALSE(calibration.valid(3, 2));
  EXPECT_TRUE(calibration.valid(5, 4));
  EXPECT_TRUE(std::isnan(calibration.evaluate(3, 2, 35.0f)[2]));
  EXPECT_TRUE(std::isnan(calibration.evaluateDepth(3, 2, 35.0f)));
  EXPECT_EQ(calibration.validCount(), static_cast<std::size_t>(truth.size.area() - 1));

  QuasiCalibrationOptions four;
  four.min_poses = 4;
  EXPECT_THROW(QuasiCalibrationFitter(truth.size, four), std::invalid_argument);
}

TEST(QuasiCalibration, ExtrapolationIsLimited) {
  const CubicTruth truth(13);
  QuasiCalibrationFitter fitter(truth.size);
  cv::Mat phase, xyz;
  for (int j = 0; j < 8; ++j) {
    truth.pose(j, 8, phase, xyz);
    fitter.addPose(phase, xyz);
  }
  QuasiCalibration calibration = fitter.fit();
  const PixelPolynomial& p = calibration.pixel(0, 0);
  const float half = 1.0f / p.phase_inv_half;
  EXPECT_FALSE(std::isnan(calibration.evaluateDepth(0, 0, p.phase_centre + 1.4f * half)));
  EXPECT_TRUE(std::isnan(calibration.evaluateDepth(0, 0, p.phase_centre + 1.6f * half)));
  EXPECT_TRUE(std::isnan(calibration.evaluateDepth(0, 0, kNaNf)));
  calibration.setExtrapolationLimit(2.0f);
  EXPECT_FALSE(std::isnan(calibration.evaluateDepth(0, 0, p.phase_centre + 1.6f * half)));
}

// ------------------------------------------------------------- realistic rig

// A 160×128 main camera (the paper's field of view), the cylindrical
// projector, and 14 calibration planes from 540 to 620 mm with tilts.
struct Rig {
  PinholeCamera camera = testing::makeCamera(160, 128, true);
  testing::PlacedCamera placed{camera};
  testing::Projector projector;
  RayMap rays{camera};

  static Plane calibrationPlane(int j) {
    const double depth = 540.0 + 80.0 * j / 13.0;
    const double tilt_x = 0.12 * std::sin(1.3 * j);
    const double tilt_y = 0.15 * std::cos(0.9 * j + 0.4);
    return Plane{{0.0, 0.0, depth}, testing::planeNormal(tilt_x, tilt_y)};
  }

  // Phase of the pose and its target points (ray ∩ plane, as the calibration
  // pipeline computes them); phase noise σ optional.
  void pose(const Plane& plane, double phase_sigma, std::mt19937_64& rng, cv::Mat& phase,
            cv::Mat& target) const {
    target = intersectRaysWithPlane(rays, plane);
    phase = testing::renderPhase(placed, plane, projector);
    std::normal_distribution<double> noise(0.0, phase_sigma);
    if (phase_sigma > 0.0)
      for (auto it = phase.begin<float>(); it != phase.end<float>(); ++it)
        *it = static_cast<float>(*it + noise(rng));
  }

  QuasiCalibration calibrate(double phase_sigma, CalibrationResiduals* residuals) const {
    std::mt19937_64 rng(21);
    QuasiCalibrationFitter fitter(camera.image_size);
    std::vector<cv::Mat> phases(14), targets(14);
    for (int j = 0; j < 14; ++j) {
      pose(calibrationPlane(j), phase_sigma, rng, phases[j], targets[j]);
      fitter.addPose(phases[j], targets[j]);
    }
    QuasiCalibration calibration = fitter.fit();
    QuasiCalibrationResiduals second_pass(calibration);
    for (int j = 0; j < 14; ++j)
      second_pass.addPose(phases[j], targets[j]);
    *residuals = second_pass.result();
    calibration.setResidualSummary(static_cast<float>(residuals->pooled_depth_rmse_mm),
                                   static_cast<float>(residuals->sensitivity_mm_per_rad));
    return calibration;
  }
};

// Along a pixel's ray the azimuth projector's Φ ↦ point map is a Möbius
// function of tan(Φ/a), not a cubic: with the projector ~0.2 rad off the ray's
// azimuth and 0.03 rad of azimuth over 540–620 mm, the least-squares cubic
// leaves ~1e-3 mm (the fourth-order term), far below the paper's 0.085 mm.
constexpr double kModelError = 3e-3;

TEST(QuasiCalibration, ReconstructsAHeldOutPlane) {
  const Rig rig;
  CalibrationResiduals residuals;
  const QuasiCalibration calibration = rig.calibrate(0.0, &residuals);
  EXPECT_EQ(calibration.validCount(), 160u * 128u);
  ASSERT_EQ(residuals.poses.size(), 14u);
  for (const PoseResidual& pose : residuals.poses) {
    EXPECT_EQ(pose.pixel_count, 160u * 128u);
    EXPECT_LT(pose.depth_rmse_mm, kModelError);
    EXPECT_LT(pose.distance_rmse_mm, kModelError);
  }
  EXPECT_LT(residuals.pooled_depth_rmse_mm, kModelError);

  // A plane not among the calibration poses, its phase rendered by the test's
  // own ray model; truth = the same rays on the true plane.
  const Plane held_out{{3.0, -2.0, 577.0}, testing::planeNormal(-0.08, 0.2)};
  cv::Mat truth;
  const cv::Mat phase = testing::renderPhase(rig.placed, held_out, rig.projector, &truth);
  const cv::Mat xyz = calibration.evaluate(phase);
  const cv::Mat depth = calibration.evaluateDepth(phase);
  double sum = 0.0, worst = 0.0, worst_plane = 0.0;
  for (int v = 0; v < 128; ++v) {
    for (int u = 0; u < 160; ++u) {
      const cv::Vec3f p = xyz.at<cv::Vec3f>(v, u);
      const cv::Vec3d t = truth.at<cv::Vec3d>(v, u);
      ASSERT_FALSE(std::isnan(p[2]));
      const double e = cv::norm(cv::Vec3d(p[0], p[1], p[2]) - t);
      sum += e * e;
      worst = std::max(worst, e);
      worst_plane = std::max(worst_plane,
                             std::abs(held_out.signedDistance(Eigen::Vector3d(p[0], p[1], p[2]))));
      EXPECT_EQ(std::bit_cast<std::uint32_t>(depth.at<float>(v, u)),
                std::bit_cast<std::uint32_t>(p[2]));
      EXPECT_EQ(
          std::bit_cast<std::uint32_t>(calibration.evaluateDepth(u, v, phase.at<float>(v, u))),
          std::bit_cast<std::uint32_t>(p[2]));
    }
  }
  const double rmse = std::sqrt(sum / (160.0 * 128.0));
  EXPECT_LT(rmse, kModelError) << "held-out 3D RMSE " << rmse;
  EXPECT_LT(worst, 4 * kModelError) << "held-out worst 3D error " << worst;
  RecordProperty("held_out_rmse_mm", std::to_string(rmse));
  RecordProperty("held_out_worst_mm", std::to_string(worst));
  RecordProperty("held_out_worst_plane_mm", std::to_string(worst_plane));
  std::cout << "quasi-calibration: pooled RMSE " << residuals.pooled_depth_rmse_mm
            << " mm; held-out plane 3D RMSE " << rmse << " mm, worst " << worst
            << " mm, worst distance to the plane " << worst_plane << " mm\n";

  // S_eff = <|∂Z/∂Φ|>: compare with the truth by finite differences along
  // each pixel's ray on the centre pose.
  double truth_slope = 0.0;
  int n = 0;
  for (int v = 0; v < 128; v += 4) {
    for (int u = 0; u < 160; u += 4) {
      const Eigen::Vector3d d = testing::pixelRay(rig.camera, u, v);
      const double t0 = 580.0 / d.z();
      const double h = 0.01;
      const double dphi = rig.projector.phase((t0 + h) * d) - rig.projector.phase((t0 - h) * d);
      truth_slope += std::abs(2 * h * d.z() / dphi);
      ++n;
    }
  }
  truth_slope /= n;
  EXPECT_NEAR(residuals.sensitivity_mm_per_rad, truth_slope, 0.02 * truth_slope);
  RecordProperty("s_eff_mm_per_rad", std::to_string(residuals.sensitivity_mm_per_rad));
  std::cout << "S_eff " << residuals.sensitivity_mm_per_rad << " mm/rad (truth " << truth_slope
            << ")\n";
}

TEST(QuasiCalibration, PooledRmseReflectsPhaseNoise) {
  // With phase noise σφ the depth residual of a least-squares cubic over M
  // poses has RMS S·σφ·√((M − 4)/M): Eq. (12) and S_eff are consistent.
  const Rig rig;
  const double sigma = 0.002;  // rad
  CalibrationResiduals residuals;
  const QuasiCalibration calibration = rig.calibrate(sigma, &residuals);
  const double expected = residuals.sensitivity_mm_per_rad * sigma * std::sqrt((14.0 - 4.0) / 14.0);
  EXPECT_NEAR(residuals.pooled_depth_rmse_mm, expected, 0.05 * expected);
  double sum = 0.0;
  std::size_t count = 0;
  for (const PoseResidual& pose : residuals.poses) {
    sum += pose.depth_rmse_mm * pose.depth_rmse_mm * static_cast<double>(pose.pixel_count);
    count += pose.pixel_count;
  }
  EXPECT_NEAR(residuals.pooled_depth_rmse_mm, std::sqrt(sum / static_cast<double>(count)), 1e-12);
  EXPECT_EQ(residuals.pixel_count, count);
  EXPECT_GE(residuals.pooled_distance_rmse_mm, residuals.pooled_depth_rmse_mm);
  EXPECT_FLOAT_EQ(calibration.info().pooled_rmse_mm,
                  static_cast<float>(residuals.pooled_depth_rmse_mm));
  RecordProperty("pooled_rmse_mm", std::to_string(residuals.pooled_depth_rmse_mm));
  std::cout << "phase noise " << sigma << " rad: pooled RMSE " << residuals.pooled_depth_rmse_mm
            << " mm (expected " << expected << "), 3D " << residuals.pooled_distance_rmse_mm
            << " mm\n";
}

// ------------------------------------------------------------- serialisation

QuasiCalibration smallCalibration() {
  const CubicTruth truth(14);
  QuasiCalibrationOptions options;
  options.phase_source = PhaseSource::High;
  QuasiCalibrationFitter fitter(truth.size, options);
  cv::Mat phase, xyz;
  for (int j = 0; j < 7; ++j) {
    truth.pose(j, 7, phase, xyz);
    if (j > 3) phase.at<float>(1, 1) = kNaNf;  // one invalid pixel
    fitter.addPose(phase, xyz);
  }
  QuasiCalibration calibration = fitter.fit();
  calibration.setResidualSummary(0.085f, 39.304f);
  calibration.setOrderResidual(-2.75f, 0.125f);
  return calibration;
}

bool sameBits(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() &&
         std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

TEST(QuasiCalibrationFile, RoundTripIsBitExact) {
  const QuasiCalibration original = smallCalibration();
  const std::vector<std::byte> bytes = original.serialize();
  EXPECT_EQ(bytes.size(), 72u + 24 * 16 + 24 * 16 * 56u);
  const QuasiCalibration loaded = QuasiCalibration::deserialize(bytes);
  EXPECT_EQ(loaded.serialize(), bytes);
  EXPECT_EQ(loaded.size(), original.size());
  EXPECT_EQ(loaded.info().phase_source, PhaseSource::High);
  EXPECT_EQ(loaded.info().pose_count, 7u);
  EXPECT_EQ(loaded.info().min_poses, 6u);
  EXPECT_EQ(loaded.info().pooled_rmse_mm, 0.085f);
  EXPECT_EQ(loaded.info().sensitivity_mm_per_rad, 39.304f);
  EXPECT_EQ(loaded.info().order_centre_rad, -2.75f);
  EXPECT_EQ(loaded.info().order_spread_rad, 0.125f);
  EXPECT_FALSE(loaded.valid(1, 1));
  EXPECT_EQ(std::memcmp(&loaded.pixel(5, 7), &original.pixel(5, 7), sizeof(PixelPolynomial)), 0);

  cv::Mat phase(original.size(), CV_32FC1);
  cv::randu(phase, 34.0, 36.0);
  EXPECT_TRUE(sameBits(loaded.evaluate(phase), original.evaluate(phase)));

  // In place, without a copy: the same bits again.
  const QuasiCalibrationView view = QuasiCalibrationView::fromBytes(bytes);
  EXPECT_TRUE(sameBits(view.evaluate(phase), original.evaluate(phase)));
  EXPECT_TRUE(sameBits(view.evaluateDepth(phase), original.evaluateDepth(phase)));
  EXPECT_EQ(view.validCount(), original.validCount());
}

void expectRejected(std::span<const std::byte> bytes, const std::string& fault) {
  try {
    QuasiCalibration::deserialize(bytes);
    ADD_FAILURE() << "accepted a file with: " << fault;
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr(fault));
  }
  EXPECT_THROW(QuasiCalibrationView::fromBytes(bytes), std::invalid_argument);
}

TEST(QuasiCalibrationFile, RejectsEveryCorruption) {
  const std::vector<std::byte> good = smallCalibration().serialize();

  std::vector<std::byte> flipped = good;
  flipped[good.size() / 2] ^= std::byte{0x10};
  expectRejected(flipped, "checksum mismatch");
  flipped = good;
  flipped[50] ^= std::byte{0x01};  // the pooled RMSE in the header
  expectRejected(flipped, "checksum mismatch");

  expectRejected(std::span(good).first(good.size() - 1), "truncated");
  expectRejected(std::span(good).first(40), "truncated");
  std::vector<std::byte> longer = good;
  longer.push_back(std::byte{0});
  expectRejected(longer, "trailing bytes");

  std::vector<std::byte> magic = good;
  magic[3] = std::byte{'X'};
  expectRejected(magic, "bad magic");

  std::vector<std::byte> version = good;
  version[8] = std::byte{3};
  expectRejected(version, "unsupported version 3");

  std::vector<std::byte> model = good;
  model[24] = std::byte{2};
  expectRejected(model, "unknown model id 2");

  std::vector<std::byte> absurd = good;
  absurd[16] = absurd[17] = absurd[18] = absurd[19] = std::byte{0xff};
  expectRejected(absurd, "absurd image size");

  const QuasiCalibration calibration = QuasiCalibration::deserialize(good);
  EXPECT_NO_THROW(calibration.requireImageSize(cv::Size(24, 16)));
  try {
    calibration.requireImageSize(cv::Size(160, 128));
    ADD_FAILURE() << "accepted another image size";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("made for 24x16 images"));
    EXPECT_THAT(e.what(), HasSubstr("160x128"));
  }
}

// CRC-32 (IEEE, reflected), as docs/formats.md defines the file's checksum.
std::uint32_t crc32(std::span<const std::byte> a, std::span<const std::byte> b) {
  std::uint32_t crc = 0xffffffffu;
  for (std::span<const std::byte> part : {a, b}) {
    for (std::byte byte : part) {
      crc ^= std::to_integer<std::uint32_t>(byte);
      for (int k = 0; k < 8; ++k)
        crc = (crc & 1u) ? 0xEDB88320u ^ (crc >> 1) : crc >> 1;
    }
  }
  return crc ^ 0xffffffffu;
}

// Files written before the order-residual centre was recorded (version 1, a
// 64-byte header) still load, with the centre unknown.
TEST(QuasiCalibrationFile, VersionOneLoadsWithoutAnOrderCentre) {
  const std::vector<std::byte> v2 = smallCalibration().serialize();
  std::vector<std::byte> v1(v2.begin(), v2.begin() + 64);
  v1.insert(v1.end(), v2.begin() + 72, v2.end());
  v1[8] = std::byte{1};
  v1[12] = std::byte{64};
  const std::uint32_t crc = crc32(std::span(v1).first(60), std::span(v1).subspan(64));
  for (int i = 0; i < 4; ++i)
    v1[60 + i] = static_cast<std::byte>((crc >> (8 * i)) & 0xffu);
  const QuasiCalibration loaded = QuasiCalibration::deserialize(v1);
  EXPECT_TRUE(std::isnan(loaded.info().order_centre_rad));
  EXPECT_TRUE(std::isnan(loaded.info().order_spread_rad));
  EXPECT_EQ(loaded.info().pooled_rmse_mm, 0.085f);
  const QuasiCalibration current = QuasiCalibration::deserialize(v2);
  cv::Mat phase(current.size(), CV_32FC1);
  cv::randu(phase, 34.0, 36.0);
  EXPECT_TRUE(sameBits(loaded.evaluate(phase), current.evaluate(phase)));
  EXPECT_TRUE(
      sameBits(QuasiCalibrationView::fromBytes(v1).evaluate(phase), current.evaluate(phase)));
  // Saved again, it is a version-2 file with the centre unknown.
  const std::vector<std::byte> again = loaded.serialize();
  EXPECT_EQ(again.size(), v2.size());
  EXPECT_TRUE(std::isnan(QuasiCalibration::deserialize(again).info().order_centre_rad));
  // A version-1 file is checked like any other.
  v1[100] ^= std::byte{0x01};
  expectRejected(v1, "checksum mismatch");
}

TEST(QuasiCalibrationFile, InPlaceViewNeedsAlignment) {
  const std::vector<std::byte> good = smallCalibration().serialize();
  std::vector<std::byte> shifted(good.size() + 1);
  std::memcpy(shifted.data() + 1, good.data(), good.size());
  EXPECT_NO_THROW(QuasiCalibration::deserialize(std::span(shifted).subspan(1)));
  EXPECT_THROW(QuasiCalibrationView::fromBytes(std::span(shifted).subspan(1)),
               std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::algo
