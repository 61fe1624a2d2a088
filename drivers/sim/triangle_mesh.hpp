// SPDX-License-Identifier: Apache-2.0
// Triangle meshes for scenes: a minimal PLY reader (ascii and binary
// little-endian) and ray intersection through a bounding-volume hierarchy.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "drivers/sim/geometry.hpp"

namespace cylscan::sim {

struct MeshHit {
  double t = 0;
  Vec3 normal;  // geometric normal of the triangle (unit, not oriented)
};

class TriangleMesh {
 public:
  TriangleMesh(std::vector<Vec3> vertices, std::vector<std::array<std::uint32_t, 3>> triangles);

  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<std::array<std::uint32_t, 3>>& triangles() const { return triangles_; }
  // The mesh moved: x' = position + scale · R x.
  TriangleMesh transformed(const Mat3& rotation, const Vec3& position, double scale) const;

  std::optional<MeshHit> intersect(const Ray& ray, double t_max) const;

 private:
  struct Node {
    Eigen::Vector3d lo = Eigen::Vector3d::Zero();
    Eigen::Vector3d hi = Eigen::Vector3d::Zero();
    std::uint32_t first = 0, count = 0;  // leaf: triangles [first, first + count)
    std::uint32_t left = 0, right = 0;   // inner node children
  };
  void build();
  std::uint32_t buildNode(std::uint32_t first, std::uint32_t count, int depth);

  std::vector<Vec3> vertices_;
  std::vector<std::array<std::uint32_t, 3>> triangles_;
  std::vector<Node> nodes_;
};

// Reads the triangles of a PLY file (faces with more vertices are fanned).
// Throws ConfigError naming the file on any fault.
TriangleMesh readPlyMesh(const std::filesystem::path& file);

}  // namespace cylscan::sim
