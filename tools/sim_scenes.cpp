// SPDX-License-Identifier: Apache-2.0
#include "tools/sim_scenes.hpp"

#include <cmath>
#include <optional>
#include <variant>

#include "formats/capture_bundle.hpp"

namespace cylscan::tools {

using nlohmann::json;
using sim::Vec3;

json vecJson(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

json matrixJson(const sim::Mat3& m) {
  json rows = json::array();
  for (int r = 0; r < 3; ++r)
    rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

json truthOf(const sim::SceneObject& o) {
  json t;
  if (const auto* s = std::get_if<sim::Sphere>(&o.shape)) {
    t = {{"type", "sphere"}, {"center", vecJson(s->center)}, {"radius", s->radius}};
  } else if (const auto* p = std::get_if<sim::Plane>(&o.shape)) {
    t = {{"type", "plane"},
         {"point", vecJson(p->point)},
         {"normal", vecJson(p->normal.normalized())}};
    if (p->extent) {
      t["extent"] = {(*p->extent)[0], (*p->extent)[1]};
      t["axis_u"] = vecJson(p->axisU());
    }
  } else if (const auto* b = std::get_if<sim::Box>(&o.shape)) {
    t = {{"type", "box"},
         {"center", vecJson(b->center)},
         {"size", vecJson(b->size)},
         {"rotation", matrixJson(b->rotation)}};
  } else if (const auto* c = std::get_if<sim::Checkerboard>(&o.shape)) {
    t = {{"type", "checkerboard"},
         {"center", vecJson(c->center)},
         {"rotation", matrixJson(c->rotation)},
         {"cols", c->cols},
         {"rows", c->rows},
         {"square_mm", c->square_mm}};
  } else if (const auto* m = std::get_if<sim::Mesh>(&o.shape)) {
    t = {{"type", "mesh"}, {"file", m->file}, {"triangles", m->mesh->triangles().size()}};
  }
  t["name"] = o.name;
  t["albedo"] = o.albedo;
  return t;
}

json truthOf(const sim::Scene& scene) {
  if (scene.objects.size() == 1) return truthOf(scene.objects.front());
  json objects = json::array();
  for (const auto& o : scene.objects)
    objects.push_back(truthOf(o));
  return {{"type", "composite"}, {"objects", objects}};
}

sim::SceneObject sphere(const std::string& name, const Vec3& c, double r) {
  return {name, sim::Sphere{c, r}, 0.8};
}

sim::SceneObject plane(const std::string& name, const Vec3& point, double rx_deg, double ry_deg) {
  const sim::Mat3 r =
      sim::rotationFromVectorDeg({rx_deg, 0, 0}) * sim::rotationFromVectorDeg({0, ry_deg, 0});
  return {name, sim::Plane{point, r * Vec3(0, 0, -1), std::nullopt}, 0.8};
}

sim::Scene scene(const std::string& name, std::vector<sim::SceneObject> objects, double ambient) {
  sim::Scene s;
  s.name = name;
  s.ambient = ambient;
  s.objects = std::move(objects);
  return s;
}

// The built-in test scenes: spheres of the paper's 50 mm radius, a plane and
// isolated objects with depth steps.
std::vector<sim::Scene> testScenes() {
  std::vector<sim::Scene> scenes;
  scenes.push_back(scene("sphere_1", {sphere("sphere", {0, 0, 580}, 50)}));
  scenes.push_back(scene("sphere_2", {sphere("sphere", {-25, 12, 555}, 50)}));
  scenes.push_back(scene("sphere_3", {sphere("sphere", {30, -15, 605}, 50)}));
  scenes.push_back(scene("plane", {plane("plane", {0, 0, 585}, -5, 8)}));
  sim::Box box{{35, -35, 575}, {40, 40, 40}, sim::rotationFromVectorDeg({0, 35, 0})};
  scenes.push_back(scene("objects", {sphere("sphere_a", {-45, -15, 550}, 30),
                                     sphere("sphere_b", {40, 25, 612}, 25),
                                     {"box", box, 0.75}}));
  return scenes;
}

namespace {

std::string studyName(const std::string& prefix, int i, int n) {
  return prefix + formats::frameFileName(i, n);
}

}  // namespace

// Sphere poses: the 50 mm sphere with its visible cap inside the working
// volume (front 540–570 mm, limb at the centre depth 590–620 mm), offsets
// spread over the field of view. Plane poses: depths 545–615 mm, tilts up to
// ±8° (x) and ±10° (y), other angles than the calibration poses. Repeats: two
// fixed poses of each, rendered R times (each scan has its own frame numbers,
// hence its own noise).
StudyScenes studyScenes(const SimulateRequest& request) {
  StudyScenes out;
  auto spread = [](int i, int n) { return n == 1 ? 0.5 : static_cast<double>(i) / (n - 1); };
  json spheres = json::array(), planes = json::array();
  for (int i = 0; i < request.sphere_poses; ++i) {
    const double t = spread(i, request.sphere_poses);
    const Vec3 c(22 * std::sin(i * 2.3 + 0.4), 12 * std::cos(i * 1.9 + 0.2), 590 + 30 * t);
    out.scenes.push_back(
        scene(studyName("sphere_pose", i, request.sphere_poses), {sphere("sphere", c, 50)}));
    spheres.push_back(out.scenes.back().name);
  }
  for (int i = 0; i < request.plane_poses; ++i) {
    const double z = 545 + 70 * spread(i, request.plane_poses);
    out.scenes.push_back(
        scene(studyName("plane_pose", i, request.plane_poses),
              {plane("plane", {0, 0, z}, 8 * std::sin(i * 1.3 + 0.9), 10 * std::sin(i * 2.9))}));
    planes.push_back(out.scenes.back().name);
  }
  json sphere_repeats = json::array(), plane_repeats = json::array();
  if (request.repeats > 0) {
    const Vec3 sphere_at[] = {{0, 0, 600}, {-18, 10, 612}};
    struct PlaneAt {
      double z, rx_deg, ry_deg;
    };
    const PlaneAt plane_at[] = {{580, 3, -4}, {605, -1, 2}};
    for (int pose = 0; pose < 2; ++pose) {
      json s = json::array(), p = json::array();
      const std::string tag = std::to_string(pose + 1) + "_r";
      for (int r = 0; r < request.repeats; ++r) {
        out.scenes.push_back(scene(studyName("sphere_repeat" + tag, r, request.repeats),
                                   {sphere("sphere", sphere_at[pose], 50)}));
        s.push_back(out.scenes.back().name);
      }
      const PlaneAt& at = plane_at[pose];
      for (int r = 0; r < request.repeats; ++r) {
        out.scenes.push_back(scene(studyName("plane_repeat" + tag, r, request.repeats),
                                   {plane("plane", {0, 0, at.z}, at.rx_deg, at.ry_deg)}));
        p.push_back(out.scenes.back().name);
      }
      sphere_repeats.push_back(s);
      plane_repeats.push_back(p);
    }
  }
  out.index = {{"sphere_poses", spheres},
               {"plane_poses", planes},
               {"sphere_repeats", sphere_repeats},
               {"plane_repeats", plane_repeats},
               {"cameras", {"main", "aux"}}};
  return out;
}

// Drives the virtual head as the firmware drives the hardware: step pulses

json poseJson(const sim::RigidMotion& m) {
  return {{"R", matrixJson(m.r)}, {"T", vecJson(m.t)}};
}

}  // namespace cylscan::tools
