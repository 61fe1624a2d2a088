// SPDX-License-Identifier: Apache-2.0
// cylscan calibrate-head: the extrinsics of a multi-camera head (head.json,
// docs/formats.md) from ring scans of a target of spheres taken with the head on a
// turntable. Each bundle: every calibrated camera (DIR/<camera>.qcal)
// reconstructed on its own sets, the target's spheres found by RANSAC
// (algo/sphere_search); a camera that sees all of them gives a view at the
// bundle's turntable angle (capture.json "turntable_deg", or --turn
// BUNDLE=DEG). Main's views at two or more angles fix the turntable axis;
// every other camera's pose follows from its view through the known turn
// (algo/head_extrinsics).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/head_extrinsics.hpp"
#include "algo/sphere_search.hpp"
#include "algo/surface_fit.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/head_extrinsics.hpp"
#include "formats/input_error.hpp"
#include "tools/camera_reconstruction.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct CalibrateHeadRequest {
  std::string calib_dir;
  std::string out;
  std::vector<std::string> bundles;
  std::vector<std::string> turns;  // BUNDLE=DEG
  double radius_mm = 25.0;         // 0 = free radius
  int spheres = 4;
  std::string reference = "main";
  bool json = false;
};

std::map<fs::path, double> parseTurns(const std::vector<std::string>& turns) {
  std::map<fs::path, double> out;
  for (const std::string& text : turns) {
    const std::size_t eq = text.rfind('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
      throw std::invalid_argument("calibrate-head: --turn must be BUNDLE=DEG, not '" + text + "'");
    }
    double deg = 0;
    std::istringstream number(text.substr(eq + 1));
    if (!(number >> deg) || !number.eof() || !std::isfinite(deg)) {
      throw std::invalid_argument("calibrate-head: --turn " + text + ": '" + text.substr(eq + 1) +
                                  "' is not a number of degrees");
    }
    out[fs::weakly_canonical(text.substr(0, eq))] = deg;
  }
  return out;
}

double turnOf(const formats::CaptureBundleReader& bundle, const std::map<fs::path, double>& turns) {
  if (const auto it = turns.find(fs::weakly_canonical(bundle.dir())); it != turns.end())
    return it->second;
  const json& extra = bundle.info().extra;
  const auto it = extra.find("turntable_deg");
  if (it == extra.end()) {
    throw formats::InputError(
        bundle.dir() / "capture.json",
        "no \"turntable_deg\" (give the turn with --turn " + bundle.dir().string() + "=DEG)");
  }
  if (!it->is_number() || !std::isfinite(it->get<double>())) {
    throw formats::InputError(bundle.dir() / "capture.json",
                              "\"turntable_deg\" must be a finite number of degrees");
  }
  return it->get<double>();
}

struct CameraSighting {
  std::string bundle;
  std::string camera;
  double turn_deg = 0;
  std::vector<algo::FoundSphere> spheres;  // the target's, most points first
};

std::vector<Eigen::Vector3d> centresOf(const CameraSighting& s) {
  std::vector<Eigen::Vector3d> out;
  for (const algo::FoundSphere& f : s.spheres)
    out.push_back(f.fit.sphere.centre);
  return out;
}

json vectorJson(const Eigen::Vector3d& v) {
  return json::array({v.x(), v.y(), v.z()});
}

formats::HeadExtrinsics headOf(const algo::HeadExtrinsicsSolution& solution,
                               const CalibrateHeadRequest& request) {
  formats::HeadExtrinsics head;
  head.frame = request.reference;
  head.method = "turntable";
  for (const auto& [camera, pose] : solution.poses) {
    formats::CameraPose out;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        out.R[i][j] = pose.R(i, j);
      out.T[i] = pose.T(i);
    }
    head.cameras[camera] = out;
  }
  head.rms_mm = solution.rms_mm;
  formats::AxisRecord axis;
  for (int i = 0; i < 3; ++i) {
    axis.point[i] = solution.axis.point(i);
    axis.direction[i] = solution.axis.direction(i);
  }
  head.turntable_axis = axis;
  json residuals = json::object();
  for (const auto& [camera, r] : solution.residuals) {
    residuals[camera] = {
        {"rms_mm", r.rms_mm}, {"max_mm", r.max_mm}, {"spheres", r.spheres}, {"views", r.views}};
  }
  head.extra["residuals"] = residuals;
  head.extra["max_mm"] = solution.max_mm;
  head.extra["axis_angle_error_deg"] = solution.axis_angle_error_deg;
  json target = json::array();
  for (const Eigen::Vector3d& c : solution.target_centres)
    target.push_back(vectorJson(c));
  head.extra["target_centres_turn0"] = target;
  json views = json::array();
  for (const algo::ViewResidual& v : solution.views) {
    views.push_back({{"camera", v.camera},
                     {"turntable_deg", v.turn_deg},
                     {"bundle", v.source},
                     {"rms_mm", v.rms_mm},
                     {"max_mm", v.max_mm}});
  }
  head.extra["views"] = views;
  return head;
}

void runCalibrateHead(const CalibrateHeadRequest& request) {
  firmware::Stopwatch total;
  if (request.spheres < 3 || request.spheres > 8) {
    throw std::invalid_argument("calibrate-head: --spheres must be 3 to 8");
  }
  if (request.radius_mm < 0) throw std::invalid_argument("calibrate-head: --radius must be ≥ 0");
  const std::map<fs::path, double> turns = parseTurns(request.turns);
  algo::SphereSearchOptions search;
  search.radius_mm = request.radius_mm;
  search.max_spheres = static_cast<std::size_t>(request.spheres) + 2;

  std::vector<CameraSighting> sightings;
  std::set<std::string, std::less<>> calibrated;
  json seen = json::array();
  for (const std::string& dir : request.bundles) {
    const formats::CaptureBundleReader bundle(dir);
    const double turn = turnOf(bundle, turns);
    for (const std::string& camera : calibratedCameras(bundle, request.calib_dir)) {
      calibrated.insert(camera);
      const CameraReconstruction r =
          reconstructCamera(bundle, camera, calibrationFileOf(request.calib_dir, camera));
      const algo::Points3d points = algo::pointsFromXyzMap(r.xyz);
      std::vector<algo::FoundSphere> found = algo::findSpheres(points, search);
      seen.push_back({{"bundle", dir},
                      {"camera", camera},
                      {"turntable_deg", turn},
                      {"points", points.size()},
                      {"spheres", found.size()}});
      if (found.size() < static_cast<std::size_t>(request.spheres)) continue;
      found.resize(static_cast<std::size_t>(request.spheres));  // the best-supported
      sightings.push_back({dir, camera, turn, std::move(found)});
    }
  }
  for (const std::string& camera : calibrated) {
    const bool has = std::any_of(sightings.begin(), sightings.end(),
                                 [&](const CameraSighting& s) { return s.camera == camera; });
    if (!has) {
      throw std::invalid_argument("calibrate-head: camera '" + camera + "' saw the target's " +
                                  std::to_string(request.spheres) +
                                  " spheres in none of the bundles");
    }
  }
  if (!calibrated.contains(request.reference)) {
    throw formats::InputError(calibrationFileOf(request.calib_dir, request.reference),
                              "the reference camera has no calibration");
  }
  // The target's order: the reference camera's view nearest turn 0.
  const CameraSighting* reference = nullptr;
  for (const CameraSighting& s : sightings) {
    if (s.camera == request.reference &&
        (reference == nullptr || std::abs(s.turn_deg) < std::abs(reference->turn_deg)))
      reference = &s;
  }
  if (reference == nullptr) {
    throw std::invalid_argument("calibrate-head: the reference camera '" + request.reference +
                                "' saw the target in none of the bundles");
  }
  const std::vector<Eigen::Vector3d> reference_centres = centresOf(*reference);
  std::vector<algo::TargetView> views;
  views.reserve(sightings.size());
  for (const CameraSighting& s : sightings) {
    views.push_back(
        {s.camera, s.turn_deg, algo::matchTargetOrder(reference_centres, centresOf(s)), s.bundle});
  }
  const algo::HeadExtrinsicsSolution solution = algo::solveHeadExtrinsics(views, request.reference);
  const formats::HeadExtrinsics head = headOf(solution, request);
  formats::writeHeadExtrinsics(request.out, head);

  if (request.json) {
    json summary = {{"out", request.out},
                    {"cameras", head.extra["residuals"]},
                    {"rms_mm", solution.rms_mm},
                    {"max_mm", solution.max_mm},
                    {"axis",
                     {{"point", vectorJson(solution.axis.point)},
                      {"direction", vectorJson(solution.axis.direction)}}},
                    {"axis_angle_error_deg", solution.axis_angle_error_deg},
                    {"views", head.extra["views"]},
                    {"seen", seen},
                    {"timings_ms", {{"total", total.elapsedMs()}}}};
    std::cout << summary.dump() << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(4) << "calibrate-head: " << solution.poses.size()
            << " cameras from " << views.size() << " views, rms " << solution.rms_mm << " mm, max "
            << solution.max_mm << " mm -> " << request.out << "\n";
  for (const auto& [camera, r] : solution.residuals) {
    std::cout << "  " << camera << ": rms " << r.rms_mm << " mm, max " << r.max_mm << " mm ("
              << r.spheres << " centres in " << r.views << " view" << (r.views == 1 ? "" : "s")
              << ")\n";
  }
}

}  // namespace

void addCalibrateHeadCommand(CLI::App& app) {
  auto request = std::make_shared<CalibrateHeadRequest>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate-head",
      "extrinsics of a multi-camera head (head.json) from turntable scans of a sphere target");
  cmd->add_option("bundles", request->bundles,
                  "ring capture bundles of the target at turntable angles")
      ->required();
  cmd->add_option("--calib-dir", request->calib_dir, "directory of <camera>.qcal calibrations")
      ->required();
  cmd->add_option("--out", request->out, "head.json to write")->required();
  cmd->add_option(
         "--turn", request->turns,
         "BUNDLE=DEG: a bundle's turntable angle (default: its capture.json turntable_deg); "
         "repeat --turn for several")
      ->allow_extra_args(false);
  cmd->add_option("--radius", request->radius_mm,
                  "the target spheres' radius in mm, used to find them (0 = any; default 25)");
  cmd->add_option("--spheres", request->spheres, "the target's sphere count (default 4)");
  cmd->add_option("--reference", request->reference,
                  "the camera whose frame is the head frame (default main)");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runCalibrateHead(*request); });
}

}  // namespace cylscan::tools
