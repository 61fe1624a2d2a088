// SPDX-License-Identifier: Apache-2.0
#include "algo/phase_stereo.hpp"

#include <cmath>
#include <iostream>
#include <numbers>

#include <gtest/gtest.h>

#include "tests/calib/synthetic_scene.hpp"

namespace cylscan::algo {
namespace {

using testing::PlacedCamera;

// The stereo head: the main camera at the origin, the aux camera 110 mm to
// the right, toed in by 9° and pitched by 0.5°, the projector in between.
struct StereoRig {
  PlacedCamera main;
  PlacedCamera aux;
  testing::Projector projector;
  StereoGeometry geometry;

  StereoRig(int width, int height, bool distorted, double baseline_mm = 110.0,
            double toe_in_deg = 9.0) {
    main.camera = testing::makeCamera(width, height, distorted);
    aux.camera = testing::makeCamera(width, height, distorted);
    aux.camera.camera_matrix(0, 2) -= 2.1;  // the two cameras differ a little
    aux.camera.camera_matrix(0, 0) *= 1.01;
    aux.camera.camera_matrix(1, 1) *= 1.01;
    aux.centre = Eigen::Vector3d(baseline_mm, 1.5, 2.0);
    aux.rotation =
        testing::rotationYX(toe_in_deg * std::numbers::pi / 180.0, 0.5 * std::numbers::pi / 180.0);
    projector.source = Eigen::Vector3d(baseline_mm / 2, -30.0, -5.0);
    geometry.main = main.camera;
    geometry.aux = aux.camera;
    geometry.rotation = aux.rotation;  // X_aux = R·X_main + T, T = −R·C
    const cv::Vec3d c(aux.centre.x(), aux.centre.y(), aux.centre.z());
    geometry.translation = -(aux.rotation * c);
  }
};

struct Errors {
  double rmse = 0.0;
  double worst = 0.0;
  std::size_t checked = 0;
  std::size_t matched = 0;
};

// Distances of the reconstructed points to the true surface, over the main
// pixels whose true point the aux camera also sees (co-visible).
template <class Surface>
Errors measure(const PhaseStereoResult& result, const StereoRig& rig, const Surface& surface,
               const cv::Mat& truth) {
  Errors e;
  double sum = 0.0;
  for (int v = 0; v < truth.rows; ++v) {
    for (int u = 0; u < truth.cols; ++u) {
      const cv::Vec3d t = truth.at<cv::Vec3d>(v, u);
      if (std::isnan(t[0])) continue;
      const Eigen::Vector3d p(t[0], t[1], t[2]);
      if constexpr (std::is_same_v<Surface, Sphere>) {
        const Eigen::Vector3d n = (p - surface.centre).normalized();
        const Eigen::Vector3d to_main = -p.normalized();
        const Eigen::Vector3d to_aux = (rig.aux.centre - p).normalized();
        // Co-visible, and not grazing (< 65° incidence) for either camera:
        // near the limb the phase's curvature defeats any linear interpolation.
        if (n.dot(to_aux) < std::cos(65 * std::numbers::pi / 180) ||
            n.dot(to_main) < std::cos(65 * std::numbers::pi / 180))
          continue;
      }
      ++e.checked;
      const cv::Vec3f r = result.xyz.at<cv::Vec3f>(v, u);
      if (std::isnan(r[0])) continue;
      ++e.matched;
      const double d = std::abs(surface.signedDistance(Eigen::Vector3d(r[0], r[1], r[2])));
      sum += d * d;
      e.worst = std::max(e.worst, d);
    }
  }
  e.rmse = e.matched ? std::sqrt(sum / static_cast<double>(e.matched)) : 0.0;
  return e;
}

// Tolerance: float phase (|Φ| ≈ 30 rad, ulp 2e-6 rad) over a phase slope of
// ~0.1 rad/px is 2e-5 px; a disparity error δ costs Z²/(f·B)·δ ≈
// 600²/(1100·110)·δ ≈ 3 mm/px · δ. The dominant term is the bilinear
// resampling of the aux phase, ~h²Φ''/8: on a plane Φ'' is tiny (measured
// worst 5e-4 mm at 320×256); on the sphere the surface curvature adds to Φ''
// (measured ~2e-3 mm at normal incidence, 1.6e-2 mm at 65–70°, scaling as
// 1/width²: 4× smaller at 640 px). 0.02 mm bounds both below 65° incidence.
constexpr double kTolerance = 0.02;

TEST(PhaseStereo, PlanePointsLieOnThePlane) {
  const StereoRig rig(320, 256, true);
  const Plane plane{{0.0, 10.0, 585.0}, testing::planeNormal(0.1, -0.2)};
  cv::Mat truth;
  const cv::Mat main_phase = testing::renderPhase(rig.main, plane, rig.projector, &truth);
  const cv::Mat aux_phase = testing::renderPhase(rig.aux, plane, rig.projector);
  const PhaseStereo stereo(rig.geometry);
  const PhaseStereoResult result = stereo.reconstruct(main_phase, aux_phase);
  const Errors e = measure(result, rig, plane, truth);
  ASSERT_GT(e.checked, 0u);
  // The aux camera sees ~85 % of what the main one sees on this plane.
  EXPECT_GT(static_cast<double>(e.matched) / static_cast<double>(e.checked), 0.75);
  EXPECT_LT(e.worst, kTolerance) << "rmse " << e.rmse;
  ASSERT_EQ(result.points.size(), e.matched);
  ASSERT_FALSE(result.points.empty());
  ASSERT_EQ(result.pixels.size(), result.points.size());
  const cv::Point px = result.pixels[result.pixels.size() / 2];
  const cv::Vec3f at = result.xyz.at<cv::Vec3f>(px);
  EXPECT_EQ(at[0], result.points[result.points.size() / 2].x);
  RecordProperty("plane_rmse_mm", std::to_string(e.rmse));
  RecordProperty("plane_worst_mm", std::to_string(e.worst));
  std::cout << "SV plane: matched " << e.matched << "/" << e.checked << ", rmse " << e.rmse
            << " mm, worst " << e.worst << " mm\n";
}

// The virtual head's pair: a 270 mm baseline with the aux camera turned 25°
// towards the main one. Rectifying with zero disparity at infinity would push
// the two rectified views apart until nothing overlaps (a regression: 0 matches).
TEST(PhaseStereo, StronglyVergedPairStillMatches) {
  const StereoRig rig(320, 256, true, 270.0, 25.0);
  const Plane plane{{0.0, 10.0, 580.0}, testing::planeNormal(0.05, 0.1)};
  cv::Mat truth;
  const cv::Mat main_phase = testing::renderPhase(rig.main, plane, rig.projector, &truth);
  const cv::Mat aux_phase = testing::renderPhase(rig.aux, plane, rig.projector);
  const PhaseStereo stereo(rig.geometry);
  const Errors e = measure(stereo.reconstruct(main_phase, aux_phase), rig, plane, truth);
  ASSERT_GT(e.checked, 0u);
  EXPECT_GT(static_cast<double>(e.matched) / static_cast<double>(e.checked), 0.5);
  EXPECT_LT(e.worst, kTolerance) << "rmse " << e.rmse;
  std::cout << "SV verged plane: matched " << e.matched << "/" << e.checked << ", rmse " << e.rmse
            << " mm, worst " << e.worst << " mm\n";
}

TEST(PhaseStereo, SpherePointsLieOnTheSphere) {
  const StereoRig rig(320, 256, false);
  const Sphere sphere{{15.0, 5.0, 590.0}, 50.0};
  cv::Mat truth;
  const cv::Mat main_phase = testing::renderPhase(rig.main, sphere, rig.projector, &truth);
  const cv::Mat aux_phase = testing::renderPhase(rig.aux, sphere, rig.projector);
  const PhaseStereo stereo(rig.geometry);
  const PhaseStereoResult result = stereo.reconstruct(main_phase, aux_phase);
  const Errors e = measure(result, rig, sphere, truth);
  ASSERT_GT(e.checked, 1000u);
  EXPECT_GT(static_cast<double>(e.matched) / static_cast<double>(e.checked), 0.97);
  EXPECT_LT(e.worst, kTolerance) << "rmse " << e.rmse;
  RecordProperty("sphere_rmse_mm", std::to_string(e.rmse));
  RecordProperty("sphere_worst_mm", std::to_string(e.worst));
  std::cout << "SV sphere: matched " << e.matched << "/" << e.checked << ", rmse " << e.rmse
            << " mm, worst " << e.worst << " mm\n";
}

TEST(PhaseStereo, InvalidAuxPixelsAreNotInterpolatedAcross) {
  const StereoRig rig(160, 128, false);
  const Plane plane{{0.0, 0.0, 580.0}, testing::planeNormal(0.0, 0.1)};
  const cv::Mat main_phase = testing::renderPhase(rig.main, plane, rig.projector);
  cv::Mat aux_phase = testing::renderPhase(rig.aux, plane, rig.projector);
  // Knock out a vertical stripe of the aux map and offset the phase beyond it
  // (an edge): no point may come from across the hole or the edge.
  for (int v = 0; v < 128; ++v) {
    for (int u = 78; u < 82; ++u)
      aux_phase.at<float>(v, u) = testing::kNaNf;
  }
  const PhaseStereo stereo(rig.geometry);
  const cv::Mat rectified = stereo.rectifyAux(aux_phase);
  int nan = 0;
  for (auto it = rectified.begin<double>(); it != rectified.end<double>(); ++it)
    nan += std::isnan(*it);
  EXPECT_GT(nan, 4 * 100);  // the hole survives the resampling
  const PhaseStereoResult result = stereo.reconstruct(main_phase, aux_phase);
  for (const cv::Point3f& p : result.points)
    EXPECT_LT(std::abs(plane.signedDistance(Eigen::Vector3d(p.x, p.y, p.z))), kTolerance);
  EXPECT_GT(result.points.size(), 5000u);

  EXPECT_THROW(stereo.reconstruct(cv::Mat(10, 10, CV_32FC1), aux_phase), std::invalid_argument);
}

TEST(PhaseStereo, RejectsBadGeometry) {
  StereoRig rig(64, 48, false);
  rig.geometry.aux.image_size = cv::Size(32, 24);
  EXPECT_THROW(PhaseStereo{rig.geometry}, std::invalid_argument);
  StereoRig vertical(64, 48, false);
  vertical.geometry.rotation = cv::Matx33d::eye();
  vertical.geometry.translation = cv::Vec3d(0.0, -100.0, 0.0);
  EXPECT_THROW(PhaseStereo{vertical.geometry}, std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::algo
