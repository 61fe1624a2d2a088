// SPDX-License-Identifier: Apache-2.0
// The true surfaces of a scene in a simulated dataset's truth.json
// (docs/formats.md, simulated dataset): planes, spheres, boxes, and
// composites of them, in the main camera frame.
// Shared by `evaluate --truth` and `study`.
#pragma once

#include <filesystem>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "algo/geometry.hpp"

namespace cylscan::tools {

struct TrueBox {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Ones();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // box axes in the main frame

  // Signed distance to the box's surface (negative inside).
  double signedDistance(const Eigen::Vector3d& x) const;
};

using TrueShape = std::variant<algo::Plane, algo::Sphere, TrueBox>;

class SceneTruth {
 public:
  // The entry `scene` under "scenes" or "calib" of a truth.json. InputError
  // naming the file when it is missing or malformed; checkerboards and meshes
  // are refused.
  static SceneTruth read(const std::filesystem::path& truth_file, const std::string& scene);
  // One entry, already read from `file` (for messages).
  static SceneTruth fromJson(const nlohmann::json& entry, const std::filesystem::path& file,
                             const std::string& scene);

  const std::string& scene() const { return scene_; }
  const std::vector<TrueShape>& shapes() const { return shapes_; }
  // The signed distance to the nearest of the surfaces.
  double signedDistance(const Eigen::Vector3d& x) const;

 private:
  std::string scene_;
  std::vector<TrueShape> shapes_;
};

Eigen::Vector3d jsonVec3(const nlohmann::json& j, const std::filesystem::path& file,
                         const std::string& key);
// A point or direction as the JSON array jsonVec3 reads.
nlohmann::json vec3Json(const Eigen::Vector3d& v);

}  // namespace cylscan::tools
