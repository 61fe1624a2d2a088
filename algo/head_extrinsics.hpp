// SPDX-License-Identifier: Apache-2.0
// The extrinsics of a multi-camera head (head.json): each camera's pose in the
// head frame (= the `main` camera's frame), measured with the head on a
// turntable and a target of a few spheres standing still in the room.
//
// The method:
//  1. the turntable axis, in main's frame, from the target's sphere centres
//     seen by main at two or more turntable angles: every pair of views is a
//     rigid motion (Umeyama); its rotation axis gives the axis direction and
//     its fixed points (I − R)·p = t a point of the axis, least squares over
//     all pairs;
//  2. the target's centres at turn 0 in the head frame: main's views mapped
//     back through their known turns about that axis (Rodrigues), averaged;
//  3. each camera's pose: the centres it sees at turn α (its frame) against
//     the turn-0 centres turned by α about the axis (head frame), Umeyama.
//
// Convention: a turntable angle α turns what the head sees about the fitted
// axis by α, right-handed about `direction`; the direction's sign is chosen so
// that this holds for main's views, so the sign of the user's angle scale does
// not matter as long as it is the same for every bundle.
#pragma once

#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace cylscan::algo {

// X_to = R·X_from + T (mm).
struct RigidPose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d T = Eigen::Vector3d::Zero();

  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return R * x + T; }
};

// A line in main's frame: `point` is the axis point closest to main's origin,
// `direction` a unit vector.
struct TurntableAxis {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitY();

  // The rigid motion of a turn by `deg` about the axis (Rodrigues).
  RigidPose turn(double deg) const;
};

// The target's sphere centres seen by one camera at one turntable angle, in
// that camera's frame, in the target's order (the same sphere at the same
// index in every view: matchTargetOrder).
struct TargetView {
  std::string camera;
  double turn_deg = 0;
  std::vector<Eigen::Vector3d> centres;
  std::string source;  // where the view came from (a bundle), for messages
};

// The best rigid fit (Umeyama, no scale) taking `from` onto `to` (same order, ≥ 3
// non-collinear points; std::invalid_argument naming `what` otherwise).
RigidPose fitRigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                   std::string_view what = "points");

// `centres` reordered so that centre i is the sphere at index i of `reference`:
// the permutation whose rigid fit onto the reference has the smallest RMS
// residual (the target's spheres are told apart by their spacing). At most 8
// centres; the same count as the reference (std::invalid_argument otherwise).
std::vector<Eigen::Vector3d> matchTargetOrder(std::span<const Eigen::Vector3d> reference,
                                              std::span<const Eigen::Vector3d> centres);

struct ViewResidual {
  std::string camera;
  double turn_deg = 0;
  std::string source;
  double rms_mm = 0;  // of |pose·centre − predicted centre| over the view's spheres
  double max_mm = 0;
};

struct CameraResidual {
  double rms_mm = 0;
  double max_mm = 0;
  std::size_t spheres = 0;  // centres used (over all the camera's views)
  std::size_t views = 0;
};

struct HeadExtrinsicsSolution {
  TurntableAxis axis;
  // Each pair of main's views turned the target by this much more or less
  // than the turntable said (the largest |Umeyama angle − known turn|, degrees).
  double axis_angle_error_deg = 0;
  std::vector<Eigen::Vector3d> target_centres;          // head frame, turn 0
  std::map<std::string, RigidPose, std::less<>> poses;  // X_head = R·X_cam + T; main = identity
  std::map<std::string, CameraResidual, std::less<>> residuals;
  std::vector<ViewResidual> views;
  double rms_mm = 0;  // over every centre of every view
  double max_mm = 0;
};

// Solves steps 1–3 above. `views` must hold the reference camera at ≥ 2
// distinct turntable angles (at least 2° apart) and every other camera at
// least once; each view ≥ 3 non-collinear centres, all views the same count.
// std::invalid_argument naming what is missing (the camera, the view's source).
HeadExtrinsicsSolution solveHeadExtrinsics(std::span<const TargetView> views,
                                           std::string_view reference_camera = "main");

}  // namespace cylscan::algo
