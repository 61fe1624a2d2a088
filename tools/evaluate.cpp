// SPDX-License-Identifier: Apache-2.0
// cylscan evaluate plane|sphere: the paper's metrics of a point cloud
// (docs/formats.md, command line).
//
// plane: the least-squares (total) plane of all finite points and the RMSE of
// their distances; when the cloud has a `u` property (as reconstruct writes),
// also the regional RMSE of the central 30 % and the outer 30 % of the u-range
// (the observed min..max u). sphere: the free fit's radius and RMSE, and the
// sphere of radius R fitted by its centre: RMSE, signed mean and STD of the
// residuals. Plain fits over every finite point, no pre-selection, as in the
// paper. Text output in mm to 3 decimals (the paper's convention); --json
// gives full precision.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/surface_fit.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/point_cloud.hpp"
#include "tools/commands.hpp"
#include "tools/scene_truth.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

struct EvaluateRequest {
  std::string cloud;
  double radius = 0;
  std::string truth;  // truth.json of a simulated dataset (docs/formats.md)
  std::string scene;  // the scene of the cloud in it
  bool json = false;
};

// The finite points of a cloud, with their u (NaN when the cloud has none).
struct CloudPoints {
  algo::Points3d points;
  std::vector<double> u;
  bool has_u = false;
  std::size_t dropped = 0;  // non-finite points
};

CloudPoints loadPoints(const fs::path& file, std::size_t needed, const char* shape) {
  const formats::PointCloud cloud = formats::readPly(file);
  const auto& names = cloud.property_names;
  const auto u_it = std::find(names.begin(), names.end(), "u");
  const std::vector<float>* u =
      u_it == names.end() ? nullptr
                          : &cloud.properties[static_cast<std::size_t>(u_it - names.begin())];
  CloudPoints out;
  out.has_u = u != nullptr;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    if (!p.allFinite() || (u != nullptr && !std::isfinite((*u)[i]))) {
      ++out.dropped;
      continue;
    }
    out.points.push_back(p);
    if (u != nullptr) out.u.push_back((*u)[i]);
  }
  if (out.points.size() < needed) {
    throw formats::InputError(file, "has " + std::to_string(out.points.size()) +
                                        " finite points; a " + shape + " fit needs at least " +
                                        std::to_string(needed));
  }
  return out;
}

// A degenerate cloud (collinear, coplanar for a sphere) is bad input.
template <typename Fit>
auto fitOrInputError(const fs::path& file, Fit fit) {
  try {
    return fit();
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(file, e.what());
  }
}

// NaN (an empty region) as JSON null.
nlohmann::json number(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

// The cloud against the true surface: signed distances (RMSE, mean, STD).
std::optional<nlohmann::json> truthComparison(const EvaluateRequest& request,
                                              const algo::Points3d& points) {
  if (request.truth.empty()) return std::nullopt;
  if (request.scene.empty()) throw std::invalid_argument("evaluate: --truth needs --scene");
  const SceneTruth truth = SceneTruth::read(request.truth, request.scene);
  std::vector<double> d;
  d.reserve(points.size());
  for (const Eigen::Vector3d& p : points)
    d.push_back(truth.signedDistance(p));
  const algo::ResidualStats stats = algo::residualStats(d);
  nlohmann::json out = {{"scene", request.scene},
                        {"rmse_mm", stats.rmse},
                        {"mean_mm", stats.mean},
                        {"std_mm", stats.std},
                        {"points", stats.count}};
  const auto* sphere =
      truth.shapes().size() == 1 ? std::get_if<algo::Sphere>(&truth.shapes().front()) : nullptr;
  if (sphere != nullptr) {
    out["center"] = vec3Json(sphere->centre);
    out["radius_mm"] = sphere->radius;
  }
  return out;
}

void printTruth(const std::optional<nlohmann::json>& truth) {
  if (!truth) return;
  std::cout << "  against the true surface of '" << truth->at("scene").get<std::string>()
            << "': RMSE " << truth->at("rmse_mm").get<double>() << " mm, mean "
            << truth->at("mean_mm").get<double>() << " mm, STD "
            << truth->at("std_mm").get<double>() << " mm\n";
}

void runPlane(const EvaluateRequest& request) {
  const CloudPoints cloud = loadPoints(request.cloud, 3, "plane");
  const algo::PlaneFit fit =
      fitOrInputError(request.cloud, [&] { return algo::fitPlane(cloud.points); });
  const std::optional<nlohmann::json> truth = truthComparison(request, cloud.points);
  std::optional<algo::RegionalRmse> regional;
  if (cloud.has_u) {
    const auto [lo, hi] = std::minmax_element(cloud.u.begin(), cloud.u.end());
    const std::vector<double> residuals = algo::planeResiduals(cloud.points, fit.plane);
    regional = algo::regionalRmse(residuals, cloud.u, *lo, *hi);
  }
  if (request.json) {
    nlohmann::json out = {
        {"shape", "plane"},
        {"cloud", request.cloud},
        {"points", fit.count},
        {"dropped_points", cloud.dropped},
        {"rmse_mm", fit.rmse},
        {"plane", {{"point", vec3Json(fit.plane.point)}, {"normal", vec3Json(fit.plane.normal)}}}};
    if (regional) {
      out["regional"] = {{"central_rmse_mm", number(regional->central)},
                         {"outer_rmse_mm", number(regional->outer)},
                         {"central_points", regional->central_count},
                         {"outer_points", regional->outer_count}};
    }
    if (truth) out["truth"] = *truth;
    std::cout << out.dump() << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "plane: " << fit.count << " points, RMSE "
            << fit.rmse << " mm\n";
  if (regional) {
    std::cout << "  regional RMSE: central 30 % " << regional->central << " mm, outer 30 % "
              << regional->outer << " mm\n";
  }
  printTruth(truth);
}

void runSphere(const EvaluateRequest& request) {
  const CloudPoints cloud = loadPoints(request.cloud, 4, "sphere");
  const algo::SphereFit free =
      fitOrInputError(request.cloud, [&] { return algo::fitSphere(cloud.points); });
  const algo::FixedRadiusSphereFit fixed = fitOrInputError(
      request.cloud, [&] { return algo::fitSphereFixedRadius(cloud.points, request.radius); });
  std::optional<nlohmann::json> truth = truthComparison(request, cloud.points);
  if (truth && truth->contains("center")) {
    (*truth)["centre_offset_mm"] =
        vec3Json(free.sphere.centre - jsonVec3(truth->at("center"), request.truth, "center"));
  }
  if (request.json) {
    nlohmann::json out{{"shape", "sphere"},
                       {"cloud", request.cloud},
                       {"points", free.count},
                       {"dropped_points", cloud.dropped},
                       {"free",
                        {{"radius_mm", free.sphere.radius},
                         {"rmse_mm", free.rmse},
                         {"centre", vec3Json(free.sphere.centre)}}},
                       {"reference",
                        {{"radius_mm", request.radius},
                         {"rmse_mm", fixed.residuals.rmse},
                         {"mean_mm", fixed.residuals.mean},
                         {"std_mm", fixed.residuals.std},
                         {"centre", vec3Json(fixed.sphere.centre)}}}};
    if (truth) out["truth"] = *truth;
    std::cout << out.dump() << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "sphere: " << free.count
            << " points, free fit radius " << free.sphere.radius << " mm, RMSE " << free.rmse
            << " mm\n  reference R = " << request.radius << " mm: RMSE " << fixed.residuals.rmse
            << " mm, mean " << fixed.residuals.mean << " mm, STD " << fixed.residuals.std
            << " mm\n";
  printTruth(truth);
}

}  // namespace

void addEvaluateCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("evaluate", "the paper's metrics of a point cloud");
  cmd->require_subcommand(1);

  auto plane = std::make_shared<EvaluateRequest>();
  CLI::App* plane_cmd = cmd->add_subcommand("plane", "least-squares plane RMSE of a cloud");
  plane_cmd->add_option("cloud", plane->cloud, "point cloud (PLY)")->required();
  plane_cmd->add_option("--truth", plane->truth,
                        "truth.json of a simulated dataset: also compare with the true surface");
  plane_cmd->add_option("--scene", plane->scene, "the cloud's scene in --truth (e.g. sphere_1)");
  plane_cmd->add_flag("--json", plane->json, "print the result as one JSON object");
  plane_cmd->callback([plane] { runPlane(*plane); });

  auto sphere = std::make_shared<EvaluateRequest>();
  CLI::App* sphere_cmd =
      cmd->add_subcommand("sphere", "sphere radius and residuals against radius R");
  sphere_cmd->add_option("cloud", sphere->cloud, "point cloud (PLY)")->required();
  sphere_cmd->add_option("--radius", sphere->radius, "reference radius R (mm)")
      ->required()
      ->check(CLI::PositiveNumber);
  sphere_cmd->add_option("--truth", sphere->truth,
                         "truth.json of a simulated dataset: also compare with the true surface");
  sphere_cmd->add_option("--scene", sphere->scene, "the cloud's scene in --truth (e.g. sphere_1)");
  sphere_cmd->add_flag("--json", sphere->json, "print the result as one JSON object");
  sphere_cmd->callback([sphere] { runSphere(*sphere); });
}

}  // namespace cylscan::tools
