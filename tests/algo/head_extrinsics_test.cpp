// SPDX-License-Identifier: Apache-2.0
#include "algo/head_extrinsics.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

namespace cylscan::algo {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = std::numbers::pi / 180.0;

// A head like board/sim360: main at the origin, the projector axis 120 mm
// beside it (x), vertical (y); the turntable axis near it, slightly tilted.
TurntableAxis trueAxis() {
  TurntableAxis axis;
  axis.direction = Eigen::Vector3d(0.012, -1.0, 0.007).normalized();
  axis.point = Eigen::Vector3d(117.0, 0.0, 3.5);
  axis.point -= axis.direction.dot(axis.point) * axis.direction;
  return axis;
}

// The projector axis (x = 120, z = 0, along y).
RigidPose aboutProjector(double deg) {
  TurntableAxis projector;
  projector.point = Eigen::Vector3d(120.0, 0.0, 0.0);
  projector.direction = Eigen::Vector3d(0.0, -1.0, 0.0);
  return projector.turn(deg);
}

// Four spheres, not coplanar, in main's working volume (540–620 mm).
std::vector<Eigen::Vector3d> targetAtTurn0() {
  return {{-45.0, -30.0, 565.0}, {25.0, -18.0, 600.0}, {-5.0, 38.0, 585.0}, {30.0, 22.0, 548.0}};
}

struct Rig {
  TurntableAxis axis = trueAxis();
  std::map<std::string, RigidPose> poses;  // X_main = R·X_cam + T
  std::map<std::string, double> turn;      // the turn that brings the target before each camera
};

// camA = main turned by A about the projector axis, plus a small mounting error.
Rig makeRig() {
  Rig rig;
  rig.poses["main"] = RigidPose{};
  int i = 0;
  for (const double a : {90.0, 180.0, 270.0}) {
    RigidPose pose = aboutProjector(a);
    const Eigen::Matrix3d mount =
        Eigen::AngleAxisd(0.3 * kDeg * (i + 1), Eigen::Vector3d(1, 2, -1).normalized())
            .toRotationMatrix();
    pose.R = pose.R * mount;
    pose.T += Eigen::Vector3d(0.4 * i, -0.7, 0.2 * i);
    const std::string name = "cam" + std::to_string(static_cast<int>(a));
    rig.poses[name] = pose;
    rig.turn[name] = a;
    ++i;
  }
  return rig;
}

TargetView viewOf(const Rig& rig, const std::string& camera, double turn, double sigma,
                  std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  TargetView view;
  view.camera = camera;
  view.turn_deg = turn;
  const RigidPose t = rig.axis.turn(turn);
  const RigidPose& pose = rig.poses.at(camera);
  for (const Eigen::Vector3d& c : targetAtTurn0()) {
    const Eigen::Vector3d in_camera = pose.R.transpose() * (t.apply(c) - pose.T);
    view.centres.push_back(in_camera + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  return view;
}

std::vector<TargetView> viewsOf(const Rig& rig, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<TargetView> views;
  for (const double turn : {0.0, 8.0, -8.0})
    views.push_back(viewOf(rig, "main", turn, sigma, rng));
  for (const auto& [camera, turn] : rig.turn)
    views.push_back(viewOf(rig, camera, turn, sigma, rng));
  return views;
}

double rotationErrorDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() / kDeg;
}

TEST(HeadExtrinsics, TurnIsRodriguesAboutTheLine) {
  const TurntableAxis axis = trueAxis();
  const RigidPose t = axis.turn(37.0);
  // Points on the axis stay; others turn by 37° about it.
  const Eigen::Vector3d on_axis = axis.point + 250.0 * axis.direction;
  EXPECT_LT((t.apply(on_axis) - on_axis).norm(), 1e-9);
  EXPECT_NEAR(Eigen::AngleAxisd(t.R).angle() / kDeg, 37.0, 1e-9);
  EXPECT_GT(Eigen::AngleAxisd(t.R).axis().dot(axis.direction), 0.999999);
}

TEST(HeadExtrinsics, ExactCentresGiveTheExactPoses) {
  const Rig rig = makeRig();
  const HeadExtrinsicsSolution s = solveHeadExtrinsics(viewsOf(rig, 0.0, 1));
  EXPECT_GT(s.axis.direction.dot(rig.axis.direction), 1.0 - 1e-12);
  EXPECT_LT((s.axis.point - rig.axis.point).norm(), 1e-6);
  for (const auto& [camera, pose] : rig.poses) {
    SCOPED_TRACE(camera);
    ASSERT_TRUE(s.poses.contains(camera));
    EXPECT_LT(rotationErrorDeg(s.poses.at(camera).R, pose.R), 1e-7);
    EXPECT_LT((s.poses.at(camera).T - pose.T).norm(), 1e-6);
  }
  EXPECT_LT(s.rms_mm, 1e-6);
  EXPECT_LT(s.axis_angle_error_deg, 1e-7);
  EXPECT_EQ(s.residuals.at("main").views, 3u);
  EXPECT_EQ(s.residuals.at("cam90").spheres, 4u);
}

TEST(HeadExtrinsics, RecoversAKnownRigWithinTheNoisePropagation) {
  const Rig rig = makeRig();
  // σ = 0.005 mm per centre coordinate: a 25 mm sphere's free-fit centre from
  // thousands of points at ~0.02 mm noise.
  const double sigma = 0.005;
  // Error propagation: a 4-sphere target ~80 mm across gives each view's
  // rotation to ~σ/(40 mm·√4) ≈ 6e-5 rad; main's turns of 8° and 16° give the
  // axis direction to δ ≈ 6e-5·√2/0.2 rad ≈ 4e-4 rad (0.025°, 1σ). A turn by α
  // about an axis off by δ is off by 2·sin(α/2)·δ ≤ 1.41·δ in rotation and, the
  // target ~600 mm from the axis, by ≤ 1.41·δ·600 ≈ 0.35 mm in position; both
  // go into the camera's pose. Bounds over 20 seeds (≈ 3σ): axis 0.1°, R 0.15°,
  // T 1 mm. (Measured: axis ≤ 0.04°, R ≤ 0.08°, T ≤ 0.22 mm.)
  double worst_angle = 0, worst_t = 0, worst_direction = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const HeadExtrinsicsSolution s = solveHeadExtrinsics(viewsOf(rig, sigma, seed));
    const double direction_error =
        std::acos(std::min(1.0, s.axis.direction.dot(rig.axis.direction))) / kDeg;
    EXPECT_LT(direction_error, 0.1) << "seed " << seed;
    worst_direction = std::max(worst_direction, direction_error);
    for (const auto& [camera, pose] : rig.poses) {
      worst_angle = std::max(worst_angle, rotationErrorDeg(s.poses.at(camera).R, pose.R));
      worst_t = std::max(worst_t, (s.poses.at(camera).T - pose.T).norm());
    }
    // The residuals see the noise (not zero) but stay of its order.
    EXPECT_GT(s.rms_mm, 0.1 * sigma);
    EXPECT_LT(s.rms_mm, 10 * sigma);
  }
  EXPECT_LT(worst_angle, 0.15);
  EXPECT_LT(worst_t, 1.0);
  RecordProperty("worst_axis_error_deg", std::to_string(worst_direction));
  RecordProperty("worst_rotation_error_deg", std::to_string(worst_angle));
  RecordProperty("worst_translation_error_mm", std::to_string(worst_t));
}

TEST(HeadExtrinsics, TheSignOfTheTurnScaleDoesNotMatter) {
  Rig rig = makeRig();
  rig.axis.direction = -rig.axis.direction;  // the user's angles count the other way
  const HeadExtrinsicsSolution s = solveHeadExtrinsics(viewsOf(rig, 0.0, 1));
  for (const auto& [camera, pose] : rig.poses)
    EXPECT_LT((s.poses.at(camera).T - pose.T).norm(), 1e-6) << camera;
}

TEST(HeadExtrinsics, MatchTargetOrderUndoesAPermutation) {
  const Rig rig = makeRig();
  std::mt19937_64 rng(3);
  const TargetView view = viewOf(rig, "cam180", 180.0, 0.01, rng);
  std::vector<Eigen::Vector3d> shuffled = {view.centres[2], view.centres[0], view.centres[3],
                                           view.centres[1]};
  const std::vector<Eigen::Vector3d> reference = targetAtTurn0();
  const std::vector<Eigen::Vector3d> ordered = matchTargetOrder(reference, shuffled);
  for (std::size_t k = 0; k < 4; ++k)
    EXPECT_EQ(ordered[k], view.centres[k]) << k;
}

TEST(HeadExtrinsics, OneTurnOfMainIsNotEnough) {
  const Rig rig = makeRig();
  std::vector<TargetView> views = viewsOf(rig, 0.0, 1);
  views.erase(views.begin() + 1, views.begin() + 3);  // main at turn 0 only
  EXPECT_THAT([&] { solveHeadExtrinsics(views); },
              ::testing::ThrowsMessage<std::invalid_argument>(
                  HasSubstr("two turntable angles at least 2° apart")));
}

TEST(HeadExtrinsics, NoViewOfMainIsNamed) {
  const Rig rig = makeRig();
  std::vector<TargetView> views = viewsOf(rig, 0.0, 1);
  views.erase(views.begin(), views.begin() + 3);
  EXPECT_THAT([&] { solveHeadExtrinsics(views); }, ::testing::ThrowsMessage<std::invalid_argument>(
                                                       HasSubstr("reference camera 'main'")));
}

TEST(HeadExtrinsics, CollinearCentresAreRefusedNamingTheView) {
  const Rig rig = makeRig();
  std::vector<TargetView> views = viewsOf(rig, 0.0, 1);
  TargetView& cam = views.back();
  cam.source = "turn05";
  for (std::size_t k = 0; k < cam.centres.size(); ++k)
    cam.centres[k] = Eigen::Vector3d(10.0 * k, 2.0 * k, 500.0 + k);
  EXPECT_THAT([&] { solveHeadExtrinsics(views); },
              ::testing::ThrowsMessage<std::invalid_argument>(::testing::AllOf(
                  HasSubstr("collinear"), HasSubstr(cam.camera), HasSubstr("turn05"))));
}

TEST(HeadExtrinsics, ViewsWithDifferentSphereCountsAreRefused) {
  const Rig rig = makeRig();
  std::vector<TargetView> views = viewsOf(rig, 0.0, 1);
  views[4].centres.pop_back();
  EXPECT_THAT([&] { solveHeadExtrinsics(views); },
              ::testing::ThrowsMessage<std::invalid_argument>(HasSubstr("3 sphere centres")));
}

TEST(HeadExtrinsics, RigidFitNeedsThreePoints) {
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(fitRigid(two, two), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::algo
