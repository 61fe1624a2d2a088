// SPDX-License-Identifier: Apache-2.0
// Scenes of the virtual head: isolated objects in the main camera frame (mm),
// each with an albedo, and an ambient light level.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "drivers/sim/geometry.hpp"
#include "drivers/sim/triangle_mesh.hpp"

namespace cylscan::sim {

struct Sphere {
  Vec3 center;
  double radius = 50.0;
};

// A plane through `point` with `normal`; with `extent` a w × h rectangle
// centred on `point`, its sides along u (the main x axis projected into the
// plane, or y when x is along the normal) and v = normal × u.
struct Plane {
  Vec3 point;
  Vec3 normal{0, 0, -1};
  std::optional<std::array<double, 2>> extent;
  Vec3 axisU() const;
  Vec3 axisV() const { return normal.normalized().cross(axisU()); }
};

struct Box {
  Vec3 center;
  Vec3 size{40, 40, 40};
  Mat3 rotation = Mat3::Identity();  // box axes in the main frame
};

// A checkerboard: cols × rows inner corners, square_mm squares, surrounded by
// `margin_squares` of white. Board frame: x along cols, y along rows, z the
// normal; origin at the board centre. Inner corner (i, j) is at
// ((i − (cols−1)/2)·s, (j − (rows−1)/2)·s, 0).
struct Checkerboard {
  int cols = 9;
  int rows = 6;
  double square_mm = 12.0;
  Vec3 center{0, 0, 580};
  Mat3 rotation = Mat3::Identity();
  double albedo_dark = 0.06;
  double albedo_light = 0.85;
  int margin_squares = 1;

  std::vector<Vec3> corners() const;  // row-major, as OpenCV's findChessboardCorners orders
  double albedoAt(double x_board, double y_board) const;
  bool contains(double x_board, double y_board) const;
};

struct Mesh {
  std::shared_ptr<const TriangleMesh> mesh;  // already in the main frame
  std::string file;
};

using Shape = std::variant<Sphere, Plane, Box, Checkerboard, Mesh>;

struct SceneObject {
  std::string name;
  Shape shape;
  double albedo = 0.8;  // Lambertian albedo (the checkerboard uses its own pair)
};

struct SurfaceHit {
  double t = 0;
  Vec3 normal;  // unit, not oriented
  double albedo = 0;
  int object = -1;
};

struct Scene {
  std::string name = "scene";
  double ambient = 0.03;  // ambient irradiance: signal of albedo 1 as a fraction of full well
  std::vector<SceneObject> objects;

  std::optional<SurfaceHit> firstHit(const Ray& ray, double t_max) const;
  bool occluded(const Vec3& from, const Vec3& to) const;  // anything strictly between?
};

std::optional<SurfaceHit> intersect(const SceneObject& object, const Ray& ray, double t_max);
const char* typeName(const Shape& shape);

// Loads a scene file (TOML, see board/sim/README.md). Every fault throws
// ConfigError naming the file, line and key. Mesh files are relative to the scene file.
Scene loadScene(const std::filesystem::path& file);

}  // namespace cylscan::sim
