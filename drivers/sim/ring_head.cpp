// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/ring_head.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

namespace cylscan::sim {

RigidMotion cameraPose(const CameraParams& camera) {
  return {rotationFromVectorDeg(camera.rotation_deg), toVec(camera.position_mm)};
}

RigidMotion rotationAbout(const Vec3& point, const Vec3& direction, double angle_deg) {
  if (direction.norm() < 1e-12) throw std::invalid_argument("rotationAbout: no direction");
  const Mat3 r = Eigen::AngleAxisd(angle_deg * kDeg, direction.normalized()).toRotationMatrix();
  return {r, point - r * point};
}

SceneObject transformed(const SceneObject& object, const RigidMotion& m) {
  SceneObject out = object;
  if (auto* s = std::get_if<Sphere>(&out.shape)) {
    s->center = m.apply(s->center);
  } else if (auto* p = std::get_if<Plane>(&out.shape)) {
    const Vec3 u = p->axisU();
    p->point = m.apply(p->point);
    p->normal = m.r * p->normal;
    if (p->extent && (p->axisU() - m.r * u).norm() > 1e-9) {
      throw std::invalid_argument("scene object '" + object.name +
                                  "': a plane with an extent cannot be moved by this rotation "
                                  "(its sides follow the main x axis); use a thin box");
    }
  } else if (auto* b = std::get_if<Box>(&out.shape)) {
    b->center = m.apply(b->center);
    b->rotation = m.r * b->rotation;
  } else if (auto* c = std::get_if<Checkerboard>(&out.shape)) {
    c->center = m.apply(c->center);
    c->rotation = m.r * c->rotation;
  } else if (auto* mesh = std::get_if<Mesh>(&out.shape)) {
    mesh->mesh = std::make_shared<const TriangleMesh>(mesh->mesh->transformed(m.r, m.t, 1.0));
  }
  return out;
}

Scene transformed(const Scene& scene, const RigidMotion& motion) {
  Scene out = scene;
  for (SceneObject& o : out.objects)
    o = transformed(o, motion);
  return out;
}

std::array<double, 2> workingVolumeAzimuthDeg(const CameraModel& cam,
                                              const CylindricalProjector& projector, double near_mm,
                                              double far_mm) {
  if (!(near_mm > 0 && far_mm > near_mm)) {
    throw std::invalid_argument("camera '" + cam.params().name +
                                "': the working depths must satisfy 0 < near < far");
  }
  const Mat3 r_main_cam = cam.rotationCamFromMain().transpose();
  // A point at depth z (camera frame) on the ray through pixel (u, v), in the main frame.
  auto at = [&](double u, double v, double z) {
    const Vec3 d = cam.rotationCamFromMain() * cam.rayDirection(u, v);
    return Vec3(cam.centre() + r_main_cam * (d * (z / d.z())));
  };
  const auto& p = cam.params();
  const double reference = projector.azimuthDeg(at(p.cx, p.cy, (near_mm + far_mm) / 2));
  double lo = 1e9, hi = -1e9;
  for (double z : {near_mm, far_mm}) {
    for (int i = 0; i <= 20; ++i) {
      const double f = i / 20.0;
      const double w = cam.width() - 1.0, h = cam.height() - 1.0;
      const std::array<double, 2> border[] = {{f * w, 0}, {f * w, h}, {0, f * h}, {w, f * h}};
      for (const auto& [u, v] : border) {
        const double a =
            reference + std::remainder(projector.azimuthDeg(at(u, v, z)) - reference, 360.0);
        lo = std::min(lo, a);
        hi = std::max(hi, a);
      }
    }
  }
  return {lo, hi};
}

HeadConfig headForCamera(const HeadConfig& head, std::string_view camera, std::string_view aux) {
  const auto find = [&](std::string_view name) -> const CameraParams& {
    for (const CameraParams& c : head.cameras) {
      if (c.name == name) return c;
    }
    throw std::invalid_argument("head: no camera '" + std::string(name) + "'");
  };
  const CameraParams& view = find(camera);
  const CameraParams& beside = find(aux);
  if (camera == aux)
    throw std::invalid_argument("head: camera '" + std::string(aux) + "' is the aux");
  // X_main = R X_cam + C: a point of the old frame in the camera's frame is R^T (X − C).
  const RigidMotion to_camera = cameraPose(view).inverse();
  HeadConfig out = head;
  ProjectorParams& p = out.projector;
  p.axis_origin_mm = toArray(to_camera.apply(toVec(p.axis_origin_mm)));
  p.rotation_deg = rotationVectorDeg(to_camera.r * rotationFromVectorDeg(p.rotation_deg));
  CameraParams main = view;
  main.name = "main";
  main.position_mm = {0, 0, 0};
  main.rotation_deg = {0, 0, 0};
  out.cameras = {main, beside};
  // The frame faults follow their camera: to the new main, stay on aux, or,
  // when they were for a camera this head does not have, are gone (the stage's
  // faults are the head's and stay).
  if (head.faults.camera == camera) {
    out.faults.camera = "main";
  } else if (head.faults.camera != aux) {
    out.faults.camera = "main";
    out.faults.drop_frames = 0;
    out.faults.delay_first_frame_ms = 0;
    out.faults.corrupt_frames = 0;
  }
  validate(out);
  return out;
}

}  // namespace cylscan::sim

namespace cylscan::sim {

TurntableDesign turntableDesign(double extra_turn_deg) {
  TurntableDesign d;
  // A few mm off the projector axis (120, 0, 0) and tilted by ≈ 0.3°.
  d.axis_point = Vec3(123.0, 0.0, -2.0);
  d.axis_direction = Vec3(0.004, 1.0, -0.0025).normalized();
  // Main's working volume: a 2 × 2 layout in the image (all four spheres stay
  // inside main's view at the extra turns), the front pair on one diagonal
  // and the back pair on the other, so the centres are ≈ 30 mm off coplanar.
  for (const Vec3& c :
       {Vec3(-28, -28, 568), Vec3(28, -27, 600), Vec3(-28, 29, 603), Vec3(28, 28, 572)}) {
    d.target.push_back(Sphere{c, 25.0});
  }
  d.turns = {{0.0, "main"},      {-90.0, "cam90"},         {-180.0, "cam180"},
             {-270.0, "cam270"}, {extra_turn_deg, "main"}, {-extra_turn_deg, "main"}};
  // Main sees the check sphere at α = 20° (at (0, 0, 590) in the head frame
  // then); cam90 at α = 20° − 90°, cam270 at α = 20° + 90°.
  const double seen_by_main = 20.0;
  d.check =
      Sphere{rotationAbout(d.axis_point, d.axis_direction, seen_by_main).apply({0, 0, 590}), 50.0};
  d.check_turns = {
      {seen_by_main, "main"}, {seen_by_main - 90.0, "cam90"}, {seen_by_main + 90.0, "cam270"}};
  return d;
}

}  // namespace cylscan::sim
