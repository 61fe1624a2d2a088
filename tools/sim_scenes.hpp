// SPDX-License-Identifier: Apache-2.0
// The scenes of `cylscan simulate` and their truth (truth.json): the built-in
// test scenes, the study scenes of `cylscan study`, and the JSON of the true
// surfaces and poses, in the frame of the head's main camera (mm).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/sim/geometry.hpp"
#include "drivers/sim/ring_head.hpp"
#include "drivers/sim/scene.hpp"
#include "tools/sim_request.hpp"

namespace cylscan::tools {

nlohmann::json vecJson(const sim::Vec3& v);
nlohmann::json matrixJson(const sim::Mat3& m);
nlohmann::json poseJson(const sim::RigidMotion& m);  // {"R", "T"}
// One object's truth, or {"type": "composite", "objects": [...]} for several.
nlohmann::json truthOf(const sim::SceneObject& object);
nlohmann::json truthOf(const sim::Scene& scene);

sim::SceneObject sphere(const std::string& name, const sim::Vec3& centre, double radius);
// A plane through `point` whose normal faces the camera, tilted by rx then ry.
sim::SceneObject plane(const std::string& name, const sim::Vec3& point, double rx_deg,
                       double ry_deg);
sim::Scene scene(const std::string& name, std::vector<sim::SceneObject> objects,
                 double ambient = 0.03);

// Spheres of the paper's 50 mm radius, a plane and isolated objects with depth steps.
std::vector<sim::Scene> testScenes();

// The scenes of the paper's experiments (`cylscan study`), rendered with main
// and aux so the SV method can be compared on the same frames; `index` is
// truth.json's "study".
struct StudyScenes {
  std::vector<sim::Scene> scenes;
  nlohmann::json index = nlohmann::json::object();
};
StudyScenes studyScenes(const SimulateRequest& request);

}  // namespace cylscan::tools
