// SPDX-License-Identifier: Apache-2.0
#include "algo/stereo_refinement.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/calib/synthetic_scene.hpp"

namespace cylscan::algo {
namespace {

using testing::PlacedCamera;
constexpr double kDeg = std::numbers::pi / 180.0;

// A verged stereo pair like the head's (aux 270 mm to the right, turned ~25°
// towards the working volume at 580 mm), a projector between them, and the
// observations a calibration makes of it: checkerboard corners (with a little
// deterministic corner noise) and the absolute phase of plane poses.
struct Scene {
  PlacedCamera main, aux;
  testing::Projector projector;
  StereoGeometry truth;
  CheckerboardObservations boards;
  std::vector<PlanePoseObservation> poses;
  std::vector<Plane> true_planes;

  explicit Scene(double corner_noise_px) {
    const int w = 320, h = 256;
    main.camera = testing::makeCamera(w, h, true);
    aux.camera = testing::makeCamera(w, h, true);
    aux.camera.camera_matrix(0, 0) *= 1.001;
    aux.camera.camera_matrix(0, 2) -= 1.7;
    aux.centre = Eigen::Vector3d(270.0, 1.5, -3.0);
    aux.rotation = testing::rotationYX(25.0 * kDeg, 0.3 * kDeg);
    truth.main = main.camera;
    truth.aux = aux.camera;
    truth.rotation = aux.rotation;
    const cv::Vec3d c(aux.centre.x(), aux.centre.y(), aux.centre.z());
    truth.translation = -(aux.rotation * c);
    makeBoards(corner_noise_px);
    makePlanes();
  }

  void makeBoards(double noise_px) {
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 9; ++c)
        boards.object.emplace_back(c * 6.0f, r * 6.0f, 0.0f);
    cv::RNG rng(7);
    for (int i = 0; i < 16; ++i) {
      const cv::Vec3d rvec(0.35 * std::sin(i * 2.1), 0.4 * std::sin(i * 1.3 + 0.7),
                           0.2 * std::sin(i * 0.9));
      const cv::Vec3d tvec(-24 + 8 * std::sin(i * 1.7), -15 + 6 * std::cos(i * 2.3),
                           540 + 80 * std::fmod(i * 0.618, 1.0));
      CheckerboardView view;
      cv::projectPoints(boards.object, rvec, tvec, truth.main.camera_matrix, truth.main.dist_coeffs,
                        view.main);
      cv::Matx33d rb;
      cv::Rodrigues(rvec, rb);
      cv::Vec3d rvec_aux;
      cv::Rodrigues(truth.rotation * rb, rvec_aux);
      cv::projectPoints(boards.object, rvec_aux, truth.rotation * tvec + truth.translation,
                        truth.aux.camera_matrix, truth.aux.dist_coeffs, view.aux);
      for (auto* list : {&view.main, &view.aux})
        for (auto& p : *list)
          p += cv::Point2f(static_cast<float>(rng.gaussian(noise_px)),
                           static_cast<float>(rng.gaussian(noise_px)));
      boards.views.push_back(view);
    }
  }

  void makePlanes() {
    for (int i = 0; i < 6; ++i) {
      Plane plane;
      plane.point = Eigen::Vector3d(0, 0, 545 + 15 * i);
      plane.normal =
          testing::planeNormal(9 * std::sin(i * 2.4) * kDeg, 11 * std::sin(i * 1.7 + 1) * kDeg);
      true_planes.push_back(plane);
      PlanePoseObservation pose;
      pose.phase_main = testing::renderPhase(main, plane, projector);
      pose.phase_aux = testing::renderPhase(aux, plane, projector);
      // The initial plane is off by 0.3° and 0.4 mm, as a stereo fit with a
      // slightly wrong calibration would be.
      pose.plane.point = plane.point + Eigen::Vector3d(0, 0, 0.4);
      pose.plane.normal = (plane.normal + Eigen::Vector3d(0.005, 0, 0)).normalized();
      poses.push_back(pose);
    }
  }
};

// Errors like those a checkerboard calibration leaves: ~0.1–0.3 % focal,
// a pixel or two of principal point, hundredths of a degree of rotation.
StereoGeometry perturbed(const StereoGeometry& truth) {
  StereoGeometry g = truth;
  g.aux.camera_matrix(0, 0) *= 1.003;
  g.aux.camera_matrix(1, 1) *= 1.002;
  g.aux.camera_matrix(0, 2) += 1.5;
  g.main.dist_coeffs[0] += 0.02;
  cv::Matx33d turn;
  cv::Rodrigues(cv::Vec3d(0.0, 0.05 * kDeg, 0.02 * kDeg), turn);
  g.rotation = turn * g.rotation;
  g.translation += cv::Vec3d(0.4, -0.2, 0.5);
  return g;
}

double rotationErrorDeg(const cv::Matx33d& a, const cv::Matx33d& b) {
  cv::Vec3d r;
  cv::Rodrigues(a * b.t(), r);
  return cv::norm(r) / kDeg;
}

TEST(StereoRefinement, RecoversTheTruePairFromACheckerboardLikeStart) {
  const Scene scene(0.05);
  const StereoGeometry start = perturbed(scene.truth);
  StereoRefinementOptions options;
  options.samples_per_pose = 600;
  options.model = "k1k2";
  const StereoRefinementResult r = refineStereoWithPhase(start, scene.boards, scene.poses, options);

  EXPECT_TRUE(r.converged);
  // The phase maps are exact, so the equal-phase residual can fall to the
  // interpolation level of the bilinear aux phase; the start is far off.
  EXPECT_GT(r.before.phase_rms_px, 0.2);
  EXPECT_LT(r.after.phase_rms_px, 0.02);
  // 0.05 px of corner noise on 16 × 54 corners: the metric parameters come
  // back to well within the perturbation.
  const double fx_error =
      r.geometry.aux.camera_matrix(0, 0) / scene.truth.aux.camera_matrix(0, 0) - 1;
  EXPECT_LT(std::abs(fx_error), 5e-4) << "start 3e-3";
  EXPECT_LT(std::abs(r.geometry.aux.camera_matrix(0, 2) - scene.truth.aux.camera_matrix(0, 2)), 0.5)
      << "start 1.5 px";
  EXPECT_LT(std::abs(r.geometry.main.dist_coeffs[0] - scene.truth.main.dist_coeffs[0]), 0.005)
      << "start 0.02";
  EXPECT_LT(rotationErrorDeg(r.geometry.rotation, scene.truth.rotation), 0.01) << "start 0.054°";
  EXPECT_LT(cv::norm(r.geometry.translation - scene.truth.translation), 0.2) << "start 0.67 mm";
  // The refined planes are the true ones, to the depth scale the corner noise
  // leaves (~2e-4 of 580 mm, the same as the focal error); the start is 0.4 mm
  // and 0.3° off.
  ASSERT_EQ(r.planes.size(), scene.true_planes.size());
  for (std::size_t i = 0; i < r.planes.size(); ++i) {
    EXPECT_GT(std::abs(r.planes[i].normal.dot(scene.true_planes[i].normal)), std::cos(0.02 * kDeg));
    EXPECT_NEAR(scene.true_planes[i].signedDistance(r.planes[i].point), 0.0, 0.2);
  }
}

TEST(StereoRefinement, LeavesATrueStartWhereItIs) {
  const Scene scene(0.0);
  StereoRefinementOptions options;
  options.samples_per_pose = 400;
  options.model = "k1k2";
  std::vector<PlanePoseObservation> poses = scene.poses;
  for (std::size_t i = 0; i < poses.size(); ++i)
    poses[i].plane = scene.true_planes[i];
  const StereoRefinementResult r = refineStereoWithPhase(scene.truth, scene.boards, poses, options);
  EXPECT_LT(r.before.board_main_rms_px, 1e-3);
  EXPECT_LT(r.after.board_aux_rms_px, 1e-2);
  EXPECT_LT(rotationErrorDeg(r.geometry.rotation, scene.truth.rotation), 2e-3);
  EXPECT_LT(cv::norm(r.geometry.translation - scene.truth.translation), 0.02);
}

TEST(StereoRefinement, RejectsInputsItCannotUse) {
  const Scene scene(0.0);
  CheckerboardObservations few = scene.boards;
  few.views.resize(2);
  EXPECT_THROW(refineStereoWithPhase(scene.truth, few, scene.poses), std::invalid_argument);
  std::vector<PlanePoseObservation> one(scene.poses.begin(), scene.poses.begin() + 1);
  EXPECT_THROW(refineStereoWithPhase(scene.truth, scene.boards, one), std::invalid_argument);
  StereoRefinementOptions options;
  options.model = "k1k2k3k4";
  EXPECT_THROW(refineStereoWithPhase(scene.truth, scene.boards, scene.poses, options),
               std::invalid_argument);
  std::vector<PlanePoseObservation> wrong = scene.poses;
  cv::resize(wrong[0].phase_aux, wrong[0].phase_aux, cv::Size(100, 80));
  EXPECT_THROW(refineStereoWithPhase(scene.truth, scene.boards, wrong), std::invalid_argument);
  // A pose the aux camera cannot see at all.
  std::vector<PlanePoseObservation> blind = scene.poses;
  blind[1].phase_aux.setTo(testing::kNaNf);
  EXPECT_THROW(refineStereoWithPhase(scene.truth, scene.boards, blind), std::runtime_error);
}

}  // namespace
}  // namespace cylscan::algo
