// SPDX-License-Identifier: Apache-2.0
// The 360° virtual head (board/sim360): helpers to look at the whole head from
// one of its cameras. Several cameras sit around the projector axis; each is
// a camera of the one-direction head (board/sim's main) turned about the axis.
// The calibration of a direction reuses the one-direction datasets unchanged
// by re-expressing the head in that camera's frame (headForCamera), and the
// turntable datasets move scenes rigidly (transformed). See docs/virtual-head.md.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/scene.hpp"

namespace cylscan::sim {

// x' = r x + t.
struct RigidMotion {
  Mat3 r = Mat3::Identity();
  Vec3 t = Vec3::Zero();

  Vec3 apply(const Vec3& x) const { return r * x + t; }
  RigidMotion inverse() const { return {r.transpose(), -(r.transpose() * t)}; }
  // (*this) after `first`: x ↦ this(first(x)).
  RigidMotion after(const RigidMotion& first) const { return {r * first.r, r * first.t + t}; }
};

// A camera's pose in the head (main) frame: X_main = r · X_cam + t (t = its centre).
RigidMotion cameraPose(const CameraParams& camera);

// The rotation by angle_deg about the line through `point` along `direction`
// (right-handed about the direction; about +y, +angle increases the projector azimuth).
RigidMotion rotationAbout(const Vec3& point, const Vec3& direction, double angle_deg);

// The object / scene moved by `motion` (every shape type). A plane with an
// extent keeps its rectangle only when the motion keeps its u axis (the main
// x axis projected into the plane): std::invalid_argument otherwise, naming
// the object (use a thin box instead).
SceneObject transformed(const SceneObject& object, const RigidMotion& motion);
Scene transformed(const Scene& scene, const RigidMotion& motion);

// The projector azimuths [lo, hi] (degrees about the projector axis) that a
// camera's field of view spans between the depths near_mm and far_mm along its
// own optical axis (its border pixels' rays at both depths; board/sim's main:
// ≈ −20.15 … −2.88 over 540–620 mm). The range is unwrapped around the
// azimuth of the camera's principal ray, so it may leave (−180, 180].
std::array<double, 2> workingVolumeAzimuthDeg(const CameraModel& camera,
                                              const CylindricalProjector& projector,
                                              double near_mm = 540.0, double far_mm = 620.0);

// The head re-expressed in the frame of its camera `camera`: that camera
// becomes "main" (no pose, its own intrinsics and sensor), the projector's
// axis origin and rotation are transformed so that every point keeps its
// projector azimuth and wall angles (the cylinder's angle zero is unchanged),
// and the camera `aux` keeps its pose relative to the new main (it stands
// beside `camera` as board/sim's aux stands beside main). The other cameras
// are dropped: the result has the cameras "main" and "aux", the head of the
// one-direction datasets (cylscan simulate). std::invalid_argument naming the
// camera when the head has no such camera or no `aux`.
HeadConfig headForCamera(const HeadConfig& head, std::string_view camera,
                         std::string_view aux = "aux");

// The extrinsics dataset of the 360° head (cylscan simulate --turntable): the
// whole head stands on a turntable whose axis is near, not on, the projector
// axis (the firmware does not know it). World frame = the head frame at
// turntable angle 0; turning the head by α (right-handed about the axis
// direction, ≈ +y: + raises the azimuth of head-fixed points) maps a world
// point W to the head frame as X_head = worldToHead(α)·W.
struct TurntableDesign {
  Vec3 axis_point;      // world (= head frame at α = 0), mm
  Vec3 axis_direction;  // unit
  struct Turn {
    double turntable_deg = 0;
    std::string facing;  // the camera the target is in front of
  };
  // The target: four spheres (not coplanar) in main's working volume at α = 0.
  std::vector<Sphere> target;
  std::vector<Turn> turns;  // every camera once, then main at the small extra turns
  // The held-out check: one 50 mm sphere, seen by main at one turn and by its
  // neighbours at others (never by two cameras in one acquisition).
  Sphere check;
  std::vector<Turn> check_turns;

  RigidMotion worldToHead(double turntable_deg) const {
    return rotationAbout(axis_point, axis_direction, -turntable_deg);
  }
};

// The design for a head whose cameras are `main`, `cam90`, `cam180`, `cam270`
// (board/sim360): the target is in front of camA at α = −A (the head turned
// back by A), and in front of main at the extra turns ±extra_turn_deg.
TurntableDesign turntableDesign(double extra_turn_deg);

}  // namespace cylscan::sim
