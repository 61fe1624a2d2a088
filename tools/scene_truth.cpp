// SPDX-License-Identifier: Apache-2.0
#include "tools/scene_truth.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

Eigen::Matrix3d jsonMatrix(const json& j, const fs::path& file, const std::string& key) {
  if (!j.is_array() || j.size() != 3)
    throw formats::InputError(file, "'" + key + "' must be 3 rows of 3 numbers");
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    m.row(r) = jsonVec3(j[static_cast<std::size_t>(r)], file, key).transpose();
  return m;
}

double positive(const json& value, const fs::path& file, const std::string& key) {
  if (!value.is_number() || !(value.get<double>() > 0))
    throw formats::InputError(file, "'" + key + "' must be a positive number");
  return value.get<double>();
}

TrueShape shapeOf(const json& entry, const fs::path& file, const std::string& where) {
  const std::string type = entry.is_object() ? entry.value("type", "") : "";
  auto field = [&](const char* key) { return entry.value(key, json()); };
  if (type == "plane") {
    algo::Plane plane;
    plane.point = jsonVec3(field("point"), file, where + "point");
    plane.normal = jsonVec3(field("normal"), file, where + "normal").normalized();
    return plane;
  }
  if (type == "sphere") {
    algo::Sphere sphere;
    sphere.centre = jsonVec3(field("center"), file, where + "center");
    sphere.radius = positive(field("radius"), file, where + "radius");
    return sphere;
  }
  if (type == "box") {
    TrueBox box;
    box.centre = jsonVec3(field("center"), file, where + "center");
    box.size = jsonVec3(field("size"), file, where + "size");
    box.rotation = jsonMatrix(field("rotation"), file, where + "rotation");
    return box;
  }
  throw formats::InputError(
      file, "'" + where + "type' is '" + type + "'; only plane, sphere and box surfaces are known");
}

}  // namespace

json vec3Json(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

Eigen::Vector3d jsonVec3(const json& j, const fs::path& file, const std::string& key) {
  if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
    throw formats::InputError(file, "'" + key + "' must be an array of 3 numbers");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

double TrueBox::signedDistance(const Eigen::Vector3d& x) const {
  const Eigen::Vector3d q = (rotation.transpose() * (x - centre)).cwiseAbs() - size / 2;
  const double outside = q.cwiseMax(0.0).norm();
  const double inside = std::min(q.maxCoeff(), 0.0);
  return outside + inside;
}

SceneTruth SceneTruth::read(const fs::path& truth_file, const std::string& scene) {
  const json truth = formats::readJsonFile(truth_file, 64u << 20);
  for (const char* group : {"scenes", "calib"}) {
    if (truth.contains(group) && truth[group].is_object() && truth[group].contains(scene))
      return fromJson(truth[group][scene], truth_file, scene);
  }
  throw formats::InputError(truth_file,
                            "has no scene '" + scene + "' under \"scenes\" or \"calib\"");
}

SceneTruth SceneTruth::fromJson(const json& entry, const fs::path& file, const std::string& scene) {
  SceneTruth truth;
  truth.scene_ = scene;
  const std::string where = scene + ".";
  if (entry.is_object() && entry.value("type", "") == "composite") {
    const json objects = entry.value("objects", json());
    if (!objects.is_array() || objects.empty())
      throw formats::InputError(file, "'" + where + "objects' must be a non-empty array");
    for (std::size_t i = 0; i < objects.size(); ++i)
      truth.shapes_.push_back(
          shapeOf(objects[i], file, where + "objects[" + std::to_string(i) + "]."));
  } else {
    truth.shapes_.push_back(shapeOf(entry, file, where));
  }
  return truth;
}

double SceneTruth::signedDistance(const Eigen::Vector3d& x) const {
  double best = std::numeric_limits<double>::infinity();
  for (const TrueShape& shape : shapes_) {
    const double d = std::visit([&](const auto& s) { return s.signedDistance(x); }, shape);
    if (std::abs(d) < std::abs(best)) best = d;
  }
  return best;
}

}  // namespace cylscan::tools
