// SPDX-License-Identifier: Apache-2.0
#include "tools/sim_ring.hpp"

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/sim/ring_head.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "tools/sim_capture.hpp"
#include "tools/sim_scenes.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sim::Vec3;

// The extra turns of the extrinsics dataset with the target in front of main
// (they fix the turntable axis): as large as keeps all four 25 mm spheres of
// the target wholly in main's view (its 2 × 2 layout leaves ≈ 2.8° of room
// at either side; tests/sim/ring_head_test.cpp checks 5 px of margin).
constexpr double kExtraTurnDeg = 2.5;

struct RingSetup {
  drivers::BoardProfile profile;  // the request applied to its virtual head
  firmware::ScanOptions options;  // the board's, with the request's --frames
  firmware::ScanPlan plan;
  std::vector<std::string> cameras;  // the profile's cameras (the head's names), main first

  const sim::HeadConfig& head() const { return profile.sim->head; }
  const sim::CameraParams& model(const std::string& camera) const {
    for (const auto& c : head().cameras)
      if (c.name == camera) return c;
    throw std::invalid_argument(profile.file.string() + ": the virtual head has no camera '" +
                                camera + "'");
  }
};

RingSetup ringSetup(const SimulateRequest& request) {
  RingSetup r;
  r.profile = simulationProfile(request);
  const std::string where = r.profile.file.string();
  r.options = simulationOptions(request, r.profile);
  if (r.options.plan != firmware::PlanKind::Ring) {
    throw std::invalid_argument(where + ": --camera and --turntable need [scan] plan = \"ring\"");
  }
  r.plan = firmware::planScan(r.options, r.profile.stage);
  checkPlanAgainstHead(r.plan, r.profile);
  for (const auto& cam : r.profile.cameras) {
    // The truth names the head's cameras: the board must use the same names.
    if (cam.device != cam.name) {
      throw std::invalid_argument(where + ": camera '" + cam.name +
                                  "': simulate needs device = its name");
    }
    r.cameras.push_back(cam.name);
  }
  return r;
}

json ringAcquisition(const SimulateRequest& request, const RingSetup& setup) {
  json cams = json::object();
  const sim::CylindricalProjector projector(setup.head().projector);
  for (const std::string& c : setup.cameras) {
    const auto range = sim::workingVolumeAzimuthDeg(sim::CameraModel(setup.model(c)), projector);
    cams[c] = {{"azimuth_range_deg", {range[0], range[1]}},
               {"high_deg", setup.plan.anglesDeg(c, FringeSet::High)},
               {"low_deg", setup.plan.anglesDeg(c, FringeSet::Low)}};
  }
  return {{"plan", "ring"},
          {"ring", firmware::ringLayoutJson(*setup.plan.ring)},
          {"steps_per_deg", setup.plan.steps_per_deg},
          {"cameras", cams},
          {"board", setup.profile.file.string()},
          {"seed", request.seed},
          {"noise_scale", setup.head().noise.scale}};
}

// --camera NAME: the one-direction dataset of NAME, on the head re-expressed
// in NAME's frame (NAME becomes "main", beside it a temporary "aux"), at the
// ring plan's angles of NAME's sets.
void writeCameraDataset(const SimulateRequest& request, const RingSetup& setup,
                        SimClock::time_point started) {
  const std::string& name = request.camera;
  const auto it = std::find(setup.cameras.begin(), setup.cameras.end(), name);
  if (it == setup.cameras.end()) {
    throw std::invalid_argument("simulate: --camera '" + name + "' is not a camera of " +
                                setup.profile.file.string());
  }
  // Each direction its own noise (main's dataset keeps --seed): the cameras
  // share their intrinsics and aux's relative pose, so with one seed their
  // checkerboard images, hence their calibration errors, would be identical.
  SimulateRequest direction = request;
  direction.seed = request.seed + static_cast<std::uint64_t>(it - setup.cameras.begin());
  drivers::BoardProfile view = setup.profile;
  view.sim->head = sim::headForCamera(setup.head(), name);
  view.sim->seed = direction.seed;
  firmware::ScanOptions view_options = setup.options;
  view_options.plan = firmware::PlanKind::Sets;
  drivers::CameraProfile main = setup.profile.camera(name);
  main.name = main.device = "main";
  main.azimuth_deg.reset();
  drivers::CameraProfile aux = main;
  aux.name = aux.device = "aux";
  view.cameras = {main, aux};
  matchCamerasToHead(view);
  writeDataset(direction, view, view_options, firmware::cameraSetsPlan(setup.plan, name),
               {{"head_camera", name}},
               {{"plan", "ring"},
                {"ring", firmware::ringLayoutJson(*setup.plan.ring)},
                {"head_pose", poseJson(sim::cameraPose(setup.model(name)))}},
               started);
}

// Ring scans of the whole head: both sweeps of the ring plan, every camera per
// trigger, each frame filed under the camera's own set.
class RingScanner {
 public:
  RingScanner(const SimulateRequest& request, const RingSetup& setup)
      : request_(request), setup_(setup), capture_(setup.profile, setup.options) {}

  void writeBundle(const fs::path& dir, const sim::Scene& s, const json& extra) {
    const sim::CameraParams& main = setup_.head().cameras.front();
    json info = {{"device", "cylscan virtual head"},
                 {"board", setup_.profile.name},
                 {"mode", firmware::toString(setup_.options.mode)},
                 {"scene", s.name},
                 {"seed", request_.seed},
                 {"exposure_us", main.exposure_us}};
    if (main.bit_depth > 8) info["bit_depth"] = main.bit_depth;
    info.update(extra);
    capture_.scanBundle(dir, s, setup_.plan, setup_.cameras, std::move(info));
    ++bundles_;
  }

  int frames() const { return capture_.triggers() * static_cast<int>(setup_.cameras.size()); }
  int bundles() const { return bundles_; }

 private:
  const SimulateRequest& request_;
  const RingSetup& setup_;
  VirtualCapture capture_;
  int bundles_ = 0;
};

void printRingSummary(const SimulateRequest& request, const RingSetup& setup,
                      const RingScanner& scanner, const std::string& what,
                      SimClock::time_point started) {
  const double seconds = std::chrono::duration<double>(SimClock::now() - started).count();
  const sim::CameraParams& main = setup.head().cameras.front();
  if (request.json) {
    std::cout << json{{"out", request.out},           {"what", what},
                      {"width", main.width},          {"height", main.height},
                      {"bundles", scanner.bundles()}, {"frames_rendered", scanner.frames()},
                      {"seed", request.seed},         {"seconds", seconds}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulate: " << what << ": " << scanner.bundles() << " ring bundles, "
              << scanner.frames() << " frames (" << main.width << "x" << main.height << ") in "
              << seconds << " s -> " << request.out << "\n";
  }
}

// --turntable: the extrinsics dataset (see sim::TurntableDesign).
void writeTurntable(const SimulateRequest& request, const RingSetup& setup,
                    SimClock::time_point started) {
  const sim::TurntableDesign d = sim::turntableDesign(kExtraTurnDeg);
  json truth;
  for (const std::string& c : setup.cameras)
    truth["head"]["cameras"][c] = poseJson(sim::cameraPose(setup.model(c)));
  for (const auto& t : d.turns) {
    if (!truth["head"]["cameras"].contains(t.facing)) {
      throw std::invalid_argument("simulate --turntable: the board has no camera '" + t.facing +
                                  "' (the turntable dataset is made for board/sim360's cameras)");
    }
  }
  truth["head"]["frame"] = "main";
  truth["head"]["convention"] = "X_main = R * X_cam + T (mm)";
  truth["turntable"] = {
      {"axis_point", vecJson(d.axis_point)},
      {"axis_direction", vecJson(d.axis_direction)},
      {"convention",
       "turning the head by turntable_deg (right-handed about axis_direction) maps a world point W "
       "(world = the head frame at turntable_deg 0) to X_head = Rot(axis, -turntable_deg) * W"}};
  json centres = json::array();
  for (const auto& s : d.target)
    centres.push_back(vecJson(s.center));
  truth["target"] = {{"radius", d.target.front().radius}, {"centers", centres}};
  truth["acquisition"] = ringAcquisition(request, setup);

  RingScanner scanner(request, setup);
  const fs::path out(request.out);
  fs::create_directories(out);
  const auto scan = [&](const std::vector<sim::Sphere>& spheres,
                        const sim::TurntableDesign::Turn& t, const fs::path& dir,
                        const std::string& name) {
    const sim::RigidMotion to_head = d.worldToHead(t.turntable_deg);
    sim::Scene sc;
    sc.name = name;
    json head_centres = json::array();
    for (std::size_t i = 0; i < spheres.size(); ++i) {
      const Vec3 c = to_head.apply(spheres[i].center);
      sc.objects.push_back(sphere("sphere_" + std::to_string(i), c, spheres[i].radius));
      head_centres.push_back(vecJson(c));
    }
    scanner.writeBundle(dir, sc, {{"turntable_deg", t.turntable_deg}});
    return json{
        {"turntable_deg", t.turntable_deg}, {"facing", t.facing}, {"centers_head", head_centres}};
  };
  const int n = static_cast<int>(d.turns.size());
  for (int i = 0; i < n; ++i) {
    const std::string id = "turn" + formats::frameFileName(i, n);
    truth["turns"][id] = scan(d.target, d.turns[static_cast<std::size_t>(i)], out / id, "target");
  }
  truth["check"] = {{"radius", d.check.radius}, {"center", vecJson(d.check.center)}};
  const int m = static_cast<int>(d.check_turns.size());
  for (int i = 0; i < m; ++i) {
    const std::string id = "turn" + formats::frameFileName(i, m);
    truth["check"]["turns"][id] =
        scan({d.check}, d.check_turns[static_cast<std::size_t>(i)], out / "check" / id, "check");
  }
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");
  printRingSummary(request, setup, scanner, "turntable", started);
}

// Neither flag: ring scans of the board's default scene (or the --scene
// files), in the head frame, with their truth.
void writeRingScenes(const SimulateRequest& request, const RingSetup& setup,
                     SimClock::time_point started) {
  std::vector<sim::Scene> scenes;
  if (request.scenes.empty()) {
    if (setup.profile.sim->scene.empty()) {
      throw std::invalid_argument(setup.profile.file.string() +
                                  ": [sim] has no scene; give --scene");
    }
    scenes.push_back(sim::loadScene(setup.profile.sim->scene));
  }
  std::set<std::string> names;
  for (const std::string& file : request.scenes) {
    scenes.push_back(sim::loadScene(file));
    if (!names.insert(scenes.back().name).second) {
      throw std::invalid_argument(file + ": scene name '" + scenes.back().name +
                                  "' is already used");
    }
  }
  RingScanner scanner(request, setup);
  const fs::path out(request.out);
  fs::create_directories(out);
  json truth = {{"frame", "main"}, {"scenes", json::object()}};
  for (const sim::Scene& s : scenes) {
    scanner.writeBundle(out / "test" / s.name, s, json::object());
    truth["scenes"][s.name] = truthOf(s);
  }
  json cams = json::object();
  for (const std::string& c : setup.cameras)
    cams[c] = poseJson(sim::cameraPose(setup.model(c)));
  truth["head"] = {{"cameras", cams}};
  truth["acquisition"] = ringAcquisition(request, setup);
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");
  printRingSummary(request, setup, scanner, "scenes", started);
}

}  // namespace

void writeRingDataset(const SimulateRequest& request, SimClock::time_point started) {
  if (!request.head.empty()) {
    throw std::invalid_argument("simulate: a ring board takes its head from [sim]; no --head");
  }
  if (!request.camera.empty() && request.turntable) {
    throw std::invalid_argument("simulate: give --camera or --turntable, not both");
  }
  const RingSetup setup = ringSetup(request);
  if (!request.camera.empty()) {
    writeCameraDataset(request, setup, started);
  } else if (request.turntable) {
    writeTurntable(request, setup, started);
  } else {
    writeRingScenes(request, setup, started);
  }
}

}  // namespace cylscan::tools
