// SPDX-License-Identifier: Apache-2.0
// The numbers of `cylscan study`: the paper's experiments summarised from the
// per-scene results of `cylscan evaluate --json` (one JSON object per scene
// and method), and the GUM budget built from them.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cylscan::tools {

// The study scenes of a dataset (truth.json "study", written by `simulate
// --sphere-poses/--plane-poses/--repeats`).
struct StudyIndex {
  std::vector<std::string> sphere_poses;
  std::vector<std::string> plane_poses;
  std::vector<std::vector<std::string>> sphere_repeats;  // [fixed pose][repetition]
  std::vector<std::vector<std::string>> plane_repeats;

  // InputError naming `file` when the entry is missing or too small for the
  // study (at least 2 poses of each and 2 repetitions of 2 fixed poses).
  static StudyIndex fromTruth(const nlohmann::json& truth, const std::filesystem::path& file);
  std::vector<std::string> sphereScenes() const;
  std::vector<std::string> planeScenes() const;
};

// evaluate's JSON of each scene, for one method.
using SceneEvaluations = std::map<std::string, nlohmann::json>;

// Sample mean and STD (divisor n − 1, as the paper's pose-to-pose STDs).
double mean(const std::vector<double>& values);
double sampleStd(const std::vector<double>& values);

// Per pose: fitted-plane RMSE, RMSE and mean against the true plane, regional
// RMSE (central / outer 30 % of u); mean and STD over the poses.
nlohmann::json planeReproducibility(const SceneEvaluations& e, const StudyIndex& index);
// Per fixed pose: the RMSE of each repetition, their mean and STD.
nlohmann::json planeRepeatability(const SceneEvaluations& e, const StudyIndex& index);
// Per pose: free-fit radius; RMSE, signed mean, STD against R fitted by its
// centre; RMSE and mean against the true sphere; averages and pose-to-pose STDs.
nlohmann::json sphereReproducibility(const SceneEvaluations& e, const StudyIndex& index);
// Per fixed pose: mean and STD over the repetitions of radius, RMSE and mean.
nlohmann::json sphereRepeatability(const SceneEvaluations& e, const StudyIndex& index);

struct BudgetSources {
  double reference_tolerance_mm = 0;  // ± of the artifact (0: the virtual sphere is exact)
  double period_deg = 5;              // θh
  double stage_resolution_deg = 0.004;
};

// algo::computeUncertaintyBudget from the study's numbers, as the paper does:
// u_rep from the largest repeatability STD of the sphere RMSE, u_repr from the
// STD of the pose-wise sphere RMSE, u_cal = pooled RMSE, u_stage from S_eff.
nlohmann::json uncertaintyBudget(const nlohmann::json& sphere_repeatability,
                                 const nlohmann::json& sphere_reproducibility,
                                 const nlohmann::json& calibration, const BudgetSources& sources);

// The acceptance checks (the study's pass/fail bounds) from its results ("methods" with
// "paper" and "ours"): [{check, measured, pass}].
nlohmann::json acceptanceChecks(const nlohmann::json& results);

}  // namespace cylscan::tools
