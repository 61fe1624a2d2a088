// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "drivers/toml_reader.hpp"

namespace cylscan::sim {

using drivers::parseTomlFile;
using drivers::TableReader;

Vec3 Plane::axisU() const {
  const Vec3 n = normal.normalized();
  Vec3 hint = Vec3::UnitX();
  if (std::abs(n.dot(hint)) > 0.9) hint = Vec3::UnitY();
  return (hint - n * n.dot(hint)).normalized();
}

std::vector<Vec3> Checkerboard::corners() const {
  std::vector<Vec3> out;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < cols; ++i) {
      const Vec3 local((i - (cols - 1) / 2.0) * square_mm, (j - (rows - 1) / 2.0) * square_mm, 0);
      out.push_back(center + rotation * local);
    }
  }
  return out;
}

bool Checkerboard::contains(double x, double y) const {
  const double hw = (cols + 1 + 2 * margin_squares) * square_mm / 2;
  const double hh = (rows + 1 + 2 * margin_squares) * square_mm / 2;
  return std::abs(x) <= hw && std::abs(y) <= hh;
}

double Checkerboard::albedoAt(double x, double y) const {
  // Square (a, b): a = 0 lies between corner columns 0 and 1.
  const double a = std::floor(x / square_mm + (cols - 1) / 2.0);
  const double b = std::floor(y / square_mm + (rows - 1) / 2.0);
  if (a < -1 || a > cols - 1 || b < -1 || b > rows - 1) return albedo_light;  // margin
  const auto parity = static_cast<long long>(a + b + 4) % 2;
  return parity == 0 ? albedo_dark : albedo_light;
}

namespace {

std::optional<SurfaceHit> hitSphere(const Sphere& s, const Ray& ray, double t_max) {
  const Vec3 oc = ray.origin - s.center;
  const double b = oc.dot(ray.dir);
  const double c = oc.squaredNorm() - s.radius * s.radius;
  const double disc = b * b - c;
  if (disc < 0) return std::nullopt;
  const double root = std::sqrt(disc);
  double t = -b - root;
  if (t <= 1e-9) t = -b + root;
  if (t <= 1e-9 || t >= t_max) return std::nullopt;
  SurfaceHit h;
  h.t = t;
  h.normal = (ray.origin + t * ray.dir - s.center) / s.radius;
  return h;
}

std::optional<SurfaceHit> hitPlane(const Plane& p, const Ray& ray, double t_max) {
  const Vec3 n = p.normal.normalized();
  const double den = n.dot(ray.dir);
  if (std::abs(den) < 1e-12) return std::nullopt;
  const double t = n.dot(p.point - ray.origin) / den;
  if (t <= 1e-9 || t >= t_max) return std::nullopt;
  if (p.extent) {
    const Vec3 d = ray.origin + t * ray.dir - p.point;
    if (std::abs(d.dot(p.axisU())) > (*p.extent)[0] / 2 ||
        std::abs(d.dot(p.axisV())) > (*p.extent)[1] / 2)
      return std::nullopt;
  }
  SurfaceHit h;
  h.t = t;
  h.normal = n;
  return h;
}

std::optional<SurfaceHit> hitBox(const Box& b, const Ray& ray, double t_max) {
  const Vec3 o = b.rotation.transpose() * (ray.origin - b.center);
  const Vec3 d = b.rotation.transpose() * ray.dir;
  const Vec3 half = b.size / 2;
  double t0 = -std::numeric_limits<double>::infinity(), t1 = -t0;
  int axis0 = -1, axis1 = -1;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-15) {
      if (std::abs(o[a]) > half[a]) return std::nullopt;
      continue;
    }
    double ta = (-half[a] - o[a]) / d[a], tb = (half[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    if (ta > t0) t0 = ta, axis0 = a;
    if (tb < t1) t1 = tb, axis1 = a;
  }
  if (t0 > t1) return std::nullopt;
  double t = t0;
  int axis = axis0;
  if (t <= 1e-9) t = t1, axis = axis1;
  if (t <= 1e-9 || t >= t_max || axis < 0) return std::nullopt;
  Vec3 n_local = Vec3::Zero();
  n_local[axis] = (o[axis] + t * d[axis]) > 0 ? 1.0 : -1.0;
  SurfaceHit h;
  h.t = t;
  h.normal = b.rotation * n_local;
  return h;
}

std::optional<SurfaceHit> hitBoard(const Checkerboard& c, const Ray& ray, double t_max) {
  const Vec3 n = c.rotation.col(2);
  const double den = n.dot(ray.dir);
  if (std::abs(den) < 1e-12) return std::nullopt;
  const double t = n.dot(c.center - ray.origin) / den;
  if (t <= 1e-9 || t >= t_max) return std::nullopt;
  const Vec3 local = c.rotation.transpose() * (ray.origin + t * ray.dir - c.center);
  if (!c.contains(local.x(), local.y())) return std::nullopt;
  SurfaceHit h;
  h.t = t;
  h.normal = n;
  h.albedo = c.albedoAt(local.x(), local.y());
  return h;
}

}  // namespace

std::optional<SurfaceHit> intersect(const SceneObject& object, const Ray& ray, double t_max) {
  std::optional<SurfaceHit> hit;
  if (const auto* s = std::get_if<Sphere>(&object.shape)) {
    hit = hitSphere(*s, ray, t_max);
  } else if (const auto* p = std::get_if<Plane>(&object.shape)) {
    hit = hitPlane(*p, ray, t_max);
  } else if (const auto* b = std::get_if<Box>(&object.shape)) {
    hit = hitBox(*b, ray, t_max);
  } else if (const auto* c = std::get_if<Checkerboard>(&object.shape)) {
    return hitBoard(*c, ray, t_max);
  } else if (const auto* m = std::get_if<Mesh>(&object.shape)) {
    if (auto mh = m->mesh->intersect(ray, t_max)) hit = SurfaceHit{mh->t, mh->normal, 0, -1};
  }
  if (hit) hit->albedo = object.albedo;
  return hit;
}

const char* typeName(const Shape& shape) {
  static constexpr const char* kNames[] = {"sphere", "plane", "box", "checkerboard", "mesh"};
  return kNames[shape.index()];
}

std::optional<SurfaceHit> Scene::firstHit(const Ray& ray, double t_max) const {
  std::optional<SurfaceHit> best;
  double limit = t_max;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (auto h = intersect(objects[i], ray, limit)) {
      limit = h->t;
      best = h;
      best->object = static_cast<int>(i);
    }
  }
  return best;
}

bool Scene::occluded(const Vec3& from, const Vec3& to) const {
  const Vec3 d = to - from;
  const double len = d.norm();
  const Ray ray{from, d / len};
  for (const SceneObject& o : objects) {
    if (intersect(o, ray, len)) return true;
  }
  return false;
}

// ---- scene files -----------------------------------------------------------

namespace {

Vec3 unitNormal(TableReader& r, std::string_view key, const Vec3& fallback) {
  const Vec3 n = toVec(r.vec3(key, toArray(fallback)));
  r.require(n.norm() > 1e-9, key, "must not be zero");
  return n.normalized();
}

SceneObject readObject(const toml::table& table, const std::filesystem::path& file, int index) {
  TableReader r(table, file.string(), "object[" + std::to_string(index) + "]");
  SceneObject obj;
  const std::string type = r.string("type", "");
  obj.name = r.string("name", type + std::to_string(index));
  obj.albedo = r.number("albedo", 0.8);
  r.require(obj.albedo >= 0 && obj.albedo <= 1, "albedo", "must be in [0, 1]");
  if (type == "sphere") {
    Sphere s;
    r.require(r.has("center"), "center", "is required");
    s.center = toVec(r.vec3("center", {}));
    s.radius = r.positive("radius", 50.0);
    obj.shape = s;
  } else if (type == "plane") {
    Plane p;
    r.require(r.has("point"), "point", "is required");
    p.point = toVec(r.vec3("point", {}));
    p.normal = unitNormal(r, "normal", Vec3(0, 0, -1));
    if (r.has("extent")) {
      const auto e = r.vec2("extent", {});
      r.require(e[0] > 0 && e[1] > 0, "extent", "must be > 0");
      p.extent = e;
    }
    obj.shape = p;
  } else if (type == "box") {
    Box b;
    r.require(r.has("center"), "center", "is required");
    b.center = toVec(r.vec3("center", {}));
    b.size = toVec(r.vec3("size", toArray(b.size)));
    r.require(b.size.minCoeff() > 0, "size", "must be > 0");
    b.rotation = rotationFromVectorDeg(r.vec3("rotation_deg", {0, 0, 0}));
    obj.shape = b;
  } else if (type == "checkerboard") {
    Checkerboard c;
    c.cols = r.integer("cols", c.cols);
    r.require(c.cols >= 2 && c.cols <= 100, "cols", "must be in [2, 100]");
    c.rows = r.integer("rows", c.rows);
    r.require(c.rows >= 2 && c.rows <= 100, "rows", "must be in [2, 100]");
    c.square_mm = r.positive("square_mm", c.square_mm);
    c.center = toVec(r.vec3("center", toArray(c.center)));
    c.rotation = rotationFromVectorDeg(r.vec3("rotation_deg", {0, 0, 0}));
    c.albedo_dark = r.number("albedo_dark", c.albedo_dark);
    c.albedo_light = r.number("albedo_light", c.albedo_light);
    r.require(c.albedo_dark >= 0 && c.albedo_dark < c.albedo_light && c.albedo_light <= 1,
              "albedo_light", "must satisfy 0 <= albedo_dark < albedo_light <= 1");
    c.margin_squares = r.integer("margin_squares", c.margin_squares);
    r.require(c.margin_squares >= 0 && c.margin_squares <= 10, "margin_squares",
              "must be in [0, 10]");
    obj.shape = c;
  } else if (type == "mesh") {
    const std::string name = r.string("file", "");
    r.require(!name.empty(), "file", "is required");
    const std::filesystem::path ply = file.parent_path() / name;
    const Mat3 rot = rotationFromVectorDeg(r.vec3("rotation_deg", {0, 0, 0}));
    const Vec3 pos = toVec(r.vec3("position", {0, 0, 0}));
    const double scale = r.positive("scale", 1.0);
    Mesh m;
    m.file = ply.string();
    m.mesh = std::make_shared<const TriangleMesh>(readPlyMesh(ply).transformed(rot, pos, scale));
    obj.shape = m;
  } else {
    r.fail("type", "must be sphere, plane, box, checkerboard or mesh (got '" + type + "')");
  }
  r.finish();
  return obj;
}

}  // namespace

Scene loadScene(const std::filesystem::path& file) {
  const toml::table root = parseTomlFile(file.string());
  TableReader r(root, file.string(), "");
  Scene scene;
  scene.name = r.string("name", file.stem().string());
  r.require(!scene.name.empty(), "name", "must not be empty");
  scene.ambient = r.nonNegative("ambient", scene.ambient);
  const toml::array* objects = r.array("object");
  if (objects == nullptr || objects->empty())
    r.fail("object", "at least one [[object]] is required");
  int index = 0;
  for (const toml::node& n : *objects) {
    const toml::table* t = n.as_table();
    if (t == nullptr) r.fail("object", "must be an array of tables ([[object]])");
    scene.objects.push_back(readObject(*t, file, index++));
  }
  r.finish();
  return scene;
}

}  // namespace cylscan::sim
