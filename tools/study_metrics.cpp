// SPDX-License-Identifier: Apache-2.0
#include "tools/study_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "algo/uncertainty_budget.hpp"
#include "formats/input_error.hpp"

namespace cylscan::tools {
namespace {

using nlohmann::json;

std::vector<std::string> names(const json& list, const std::filesystem::path& file,
                               const std::string& key) {
  if (!list.is_array()) throw formats::InputError(file, "'study." + key + "' must be an array");
  std::vector<std::string> out;
  for (const json& n : list) {
    if (!n.is_string()) throw formats::InputError(file, "'study." + key + "' must list names");
    out.push_back(n.get<std::string>());
  }
  return out;
}

std::vector<std::vector<std::string>> groups(const json& list, const std::filesystem::path& file,
                                             const std::string& key) {
  if (!list.is_array()) throw formats::InputError(file, "'study." + key + "' must be an array");
  std::vector<std::vector<std::string>> out;
  for (const json& g : list)
    out.push_back(names(g, file, key));
  return out;
}

void requireAtLeast(std::size_t count, std::size_t needed, const std::filesystem::path& file,
                    const std::string& what) {
  if (count < needed) {
    throw formats::InputError(file, "has " + std::to_string(count) + " " + what +
                                        "; the study needs at least " + std::to_string(needed));
  }
}

const json& evaluation(const SceneEvaluations& e, const std::string& scene) {
  const auto it = e.find(scene);
  if (it == e.end()) throw std::logic_error("study: scene '" + scene + "' was not evaluated");
  return it->second;
}

double number(const json& j, const json::json_pointer& at) {
  const json& v = j.at(at);
  return v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

std::vector<double> column(const json& rows, const std::string& key) {
  std::vector<double> values;
  for (const json& r : rows)
    values.push_back(r.at(key).get<double>());
  return values;
}

// The mean and STD of each key over the rows, as key_mean and key_std.
void summarise(json& out, const json& rows, const std::vector<std::string>& keys) {
  for (const std::string& key : keys) {
    const std::vector<double> v = column(rows, key);
    out[key + "_mean"] = mean(v);
    out[key + "_std"] = sampleStd(v);
  }
}

json sphereRow(const SceneEvaluations& e, const std::string& scene) {
  const json& j = evaluation(e, scene);
  return {{"scene", scene},
          {"radius", number(j, "/free/radius_mm"_json_pointer)},
          {"rmse", number(j, "/reference/rmse_mm"_json_pointer)},
          {"mean", number(j, "/reference/mean_mm"_json_pointer)},
          {"std", number(j, "/reference/std_mm"_json_pointer)},
          {"truth_rmse", number(j, "/truth/rmse_mm"_json_pointer)},
          {"truth_mean", number(j, "/truth/mean_mm"_json_pointer)},
          {"points", j.at("points")}};
}

json planeRow(const SceneEvaluations& e, const std::string& scene) {
  const json& j = evaluation(e, scene);
  json row = {{"scene", scene},
              {"rmse", number(j, "/rmse_mm"_json_pointer)},
              {"truth_rmse", number(j, "/truth/rmse_mm"_json_pointer)},
              {"truth_mean", number(j, "/truth/mean_mm"_json_pointer)},
              {"points", j.at("points")}};
  if (j.contains("regional")) {
    row["central"] = number(j, "/regional/central_rmse_mm"_json_pointer);
    row["outer"] = number(j, "/regional/outer_rmse_mm"_json_pointer);
  }
  return row;
}

// Per fixed pose: the rows of its repetitions and their summary over `keys`.
json perFixedPose(const SceneEvaluations& e, const std::vector<std::vector<std::string>>& poses,
                  json (*rowOf)(const SceneEvaluations&, const std::string&),
                  const std::vector<std::string>& keys) {
  json out = json::array();
  for (const auto& reps : poses) {
    json rows = json::array();
    for (const auto& scene : reps)
      rows.push_back(rowOf(e, scene));
    json pose = {{"repetitions", rows}};
    summarise(pose, rows, keys);
    out.push_back(pose);
  }
  return out;
}

}  // namespace

StudyIndex StudyIndex::fromTruth(const json& truth, const std::filesystem::path& file) {
  if (!truth.contains("study") || !truth["study"].is_object()) {
    throw formats::InputError(file,
                              "has no \"study\" entry (simulate it with --sphere-poses, "
                              "--plane-poses and --repeats)");
  }
  const json& s = truth["study"];
  StudyIndex index;
  index.sphere_poses = names(s.value("sphere_poses", json()), file, "sphere_poses");
  index.plane_poses = names(s.value("plane_poses", json()), file, "plane_poses");
  index.sphere_repeats = groups(s.value("sphere_repeats", json()), file, "sphere_repeats");
  index.plane_repeats = groups(s.value("plane_repeats", json()), file, "plane_repeats");
  requireAtLeast(index.sphere_poses.size(), 2, file, "sphere poses");
  requireAtLeast(index.plane_poses.size(), 2, file, "plane poses");
  requireAtLeast(index.sphere_repeats.size(), 2, file, "fixed sphere poses");
  requireAtLeast(index.plane_repeats.size(), 2, file, "fixed plane poses");
  for (const auto* g : {&index.sphere_repeats, &index.plane_repeats}) {
    for (const auto& reps : *g)
      requireAtLeast(reps.size(), 2, file, "repetitions of a fixed pose");
  }
  return index;
}

std::vector<std::string> StudyIndex::sphereScenes() const {
  std::vector<std::string> out = sphere_poses;
  for (const auto& g : sphere_repeats)
    out.insert(out.end(), g.begin(), g.end());
  return out;
}

std::vector<std::string> StudyIndex::planeScenes() const {
  std::vector<std::string> out = plane_poses;
  for (const auto& g : plane_repeats)
    out.insert(out.end(), g.begin(), g.end());
  return out;
}

double mean(const std::vector<double>& values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  return std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
}

double sampleStd(const std::vector<double>& values) {
  if (values.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const double m = mean(values);
  double sum = 0;
  for (double v : values)
    sum += (v - m) * (v - m);
  return std::sqrt(sum / static_cast<double>(values.size() - 1));
}

json planeReproducibility(const SceneEvaluations& e, const StudyIndex& index) {
  json rows = json::array();
  for (const auto& scene : index.plane_poses)
    rows.push_back(planeRow(e, scene));
  json out = {{"poses", rows}};
  summarise(out, rows, {"rmse", "truth_rmse", "truth_mean"});
  if (rows.front().contains("central")) summarise(out, rows, {"central", "outer"});
  return out;
}

json planeRepeatability(const SceneEvaluations& e, const StudyIndex& index) {
  return perFixedPose(e, index.plane_repeats, planeRow, {"rmse", "truth_rmse"});
}

json sphereReproducibility(const SceneEvaluations& e, const StudyIndex& index) {
  json rows = json::array();
  for (const auto& scene : index.sphere_poses)
    rows.push_back(sphereRow(e, scene));
  json out = {{"poses", rows}};
  summarise(out, rows, {"radius", "rmse", "mean", "std", "truth_rmse", "truth_mean"});
  double worst = 0;
  for (const json& r : rows)
    worst = std::max(worst, std::abs(r.at("radius").get<double>() - 50.0));
  out["radius_worst_error"] = worst;
  return out;
}

json sphereRepeatability(const SceneEvaluations& e, const StudyIndex& index) {
  return perFixedPose(e, index.sphere_repeats, sphereRow, {"radius", "rmse", "mean", "truth_rmse"});
}

json uncertaintyBudget(const json& sphere_repeatability, const json& sphere_reproducibility,
                       const json& calibration, const BudgetSources& sources) {
  algo::UncertaintyInputs in;
  for (const json& pose : sphere_repeatability) {
    if (pose.at("rmse_std").get<double>() >= in.repeatability_std_mm) {
      in.repeatability_std_mm = pose.at("rmse_std").get<double>();
      in.repeatability_count = static_cast<int>(pose.at("repetitions").size());
    }
  }
  in.reproducibility_std_mm = sphere_reproducibility.at("rmse_std").get<double>();
  in.reproducibility_count = static_cast<int>(sphere_reproducibility.at("poses").size());
  in.reference_tolerance_mm = sources.reference_tolerance_mm;
  in.calibration_rmse_mm = calibration.at("pooled_rmse_mm").get<double>();
  in.sensitivity_mm_per_rad = calibration.at("sensitivity_mm_per_rad").get<double>();
  in.period_deg = sources.period_deg;
  in.stage_resolution_deg = sources.stage_resolution_deg;
  const algo::UncertaintyBudget b = algo::computeUncertaintyBudget(in);
  return {{"inputs",
           {{"repeatability_std_mm", in.repeatability_std_mm},
            {"repeatability_count", in.repeatability_count},
            {"reproducibility_std_mm", in.reproducibility_std_mm},
            {"reproducibility_count", in.reproducibility_count},
            {"reference_tolerance_mm", in.reference_tolerance_mm},
            {"calibration_rmse_mm", in.calibration_rmse_mm},
            {"sensitivity_mm_per_rad", in.sensitivity_mm_per_rad},
            {"period_deg", in.period_deg},
            {"stage_resolution_deg", in.stage_resolution_deg},
            {"coverage_factor", in.coverage_factor}}},
          {"u_rep", b.u_rep},
          {"u_repr", b.u_repr},
          {"u_ref", b.u_ref},
          {"u_cal", b.u_cal},
          {"u_stage", b.u_stage},
          {"combined", b.combined},
          {"expanded", b.expanded},
          {"effective_depth_resolution", b.effective_depth_resolution_mm}};
}

namespace {

std::string mm(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4f mm", value);
  return text;
}

json check(const std::string& what, const std::string& measured, bool pass) {
  return {{"check", what}, {"measured", measured}, {"pass", pass}};
}

}  // namespace

json acceptanceChecks(const json& results) {
  const json& paper = results.at("methods").at("paper");
  const json& ours = results.at("methods").at("ours");
  json checks = json::array();
  const double worst = ours.at("sphere_reproducibility").at("radius_worst_error").get<double>();
  checks.push_back(
      check("sphere radius within 0.02 mm of 50 at every sphere pose (ours)",
            "largest deviation of r from 50: " + mm(worst) + " (paper's method " +
                mm(paper.at("sphere_reproducibility").at("radius_worst_error").get<double>()) + ")",
            worst <= 0.02));
  for (const char* shape : {"sphere", "plane"}) {
    const std::string table = std::string(shape) + "_reproducibility";
    const double p = paper.at(table).at("truth_rmse_mean").get<double>();
    const double o = ours.at(table).at("truth_rmse_mean").get<double>();
    checks.push_back(check(std::string("RMSE against the true ") + shape +
                               ", mean over poses: ours no worse than the paper's method",
                           "ours " + mm(o) + ", paper's method " + mm(p), o <= p));
    checks.push_back(check(std::string("... and better with the fused phase (") + shape + ")",
                           "ours " + mm(o) + " < " + mm(p), o < p));
  }
  for (const auto* m : {&paper, &ours}) {
    if (!m->contains("fringe_orders")) continue;
    const json& f = m->at("fringe_orders");
    const auto errors = f.at("errors").get<std::size_t>();
    checks.push_back(check(
        "no fringe-order errors on isolated objects (" + m->at("label").get<std::string>() + ")",
        std::to_string(errors) + " of " + std::to_string(f.at("points").get<std::size_t>()) +
            " points farther than " + mm(f.at("threshold_mm").get<double>()) +
            " from every true surface (worst " + mm(f.at("max_distance_mm").get<double>()) + ")",
        errors == 0));
  }
  const double plane = paper.at("plane_repeatability").at(0).at("rmse_mean").get<double>();
  checks.push_back(
      check("default noise level: paper's method on the plane at 580 mm measures "
            "0.06-0.08 mm RMSE",
            mm(plane), plane >= 0.06 && plane <= 0.08));
  return checks;
}

}  // namespace cylscan::tools
