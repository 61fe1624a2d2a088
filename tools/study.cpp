// SPDX-License-Identifier: Apache-2.0
// cylscan study: the paper's experiments on the virtual head (docs/validation.md).
//
// Simulates a dataset with the study scenes (or takes one, --dataset), then
// runs the chain, each step as its own `cylscan` subcommand (the same
// executable, --json): calibrate-stereo; calibrate with the high phase (the
// paper's method) and with the fused phase (ours); refine-stereo + calibrate
// (a third variant); reconstruct every study scene with each variant and with
// the SV method (the study scenes are rendered with main and aux, so SV runs
// on the very frames of the quasi methods); evaluate each cloud against
// R = 50 / its fitted plane and against the truth. It then summarises the
// paper's tables, the GUM budget and the acceptance checks into
// DIR/report.md, DIR/results.json and PNG figures. A failing step stops the
// study with that step's message.
#include <sys/utsname.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/stopwatch.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/file_reading.hpp"
#include "formats/images.hpp"
#include "formats/input_error.hpp"
#include "tools/cloud_errors.hpp"
#include "tools/commands.hpp"
#include "tools/report_plots.hpp"
#include "tools/scene_truth.hpp"
#include "tools/step_runner.hpp"
#include "tools/study_metrics.hpp"
#include "tools/study_report.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct StudyRequest {
  std::string out;
  std::string dataset;
  bool quick = false;
  int width = 0;
  int height = 0;
  int boards = 64;
  int sphere_poses = 10;
  int plane_poses = 10;
  int repeats = 5;
  std::uint64_t seed = 1;
  bool no_refine = false;
  bool keep_clouds = false;
  bool report_only = false;
  bool json = false;
};

constexpr double kFringeOrderThresholdMm = 5.0;
constexpr double kSphereRadiusMm = 50.0;

// A way of reconstructing: a quasi-calibration (file, phase) or the SV method.
// Its implicit (noexcept) move and destructor are its members': std::string,
// fs::path, nlohmann::json and std::map, all noexcept in the library; clang-tidy
// 14 sees a throw somewhere below them that these members never reach.
struct Method {  // NOLINT(bugprone-exception-escape)
  std::string key;
  std::string label;
  bool stereo = false;  // the SV method: main + aux, no quasi-calibration
  fs::path file;        // calibration file, or stereo.yaml for SV
  json calibration;     // calibrate's summary (quasi methods)
  SceneEvaluations evaluations;
  json fringe_orders;
};

// A simulated dataset with study scenes; every path it needs is checked first.
struct StudyDataset {
  fs::path dir;
  json truth;
  StudyIndex index;
  std::vector<std::string> calib_poses;  // bundle directories
  cv::Size grid;
  double period_deg = 5;

  static StudyDataset open(const fs::path& dir) {
    if (!fs::is_directory(dir)) throw formats::InputError(dir, "is not a directory");
    for (const char* part : {"truth.json", "stereo_truth.yaml", "board", "calib"}) {
      if (!fs::exists(dir / part))
        throw formats::InputError(dir / part, "is missing: not a simulated dataset");
    }
    StudyDataset d;
    d.dir = dir;
    d.truth = formats::readJsonFile(dir / "truth.json", 64u << 20);
    d.index = StudyIndex::fromTruth(d.truth, dir / "truth.json");
    for (const auto& entry : fs::directory_iterator(dir / "calib")) {
      if (entry.is_directory()) d.calib_poses.push_back(entry.path().string());
    }
    std::sort(d.calib_poses.begin(), d.calib_poses.end());
    std::vector<std::string> scenes = d.index.sphereScenes();
    for (const auto& s : d.index.planeScenes())
      scenes.push_back(s);
    for (const auto& scene : scenes) {
      if (!fs::exists(dir / "test" / scene / "capture.json"))
        throw formats::InputError(dir / "test" / scene / "capture.json", "is missing");
    }
    const formats::CaptureBundleReader first(dir / "test" / d.index.sphere_poses.front());
    d.grid = first.frameSize("main");
    d.period_deg = first.info().high.period_deg;
    return d;
  }

  fs::path bundle(const std::string& scene) const { return dir / "test" / scene; }
  bool hasScene(const std::string& scene) const {
    return truth.contains("scenes") && truth["scenes"].contains(scene) &&
           fs::exists(bundle(scene) / "capture.json");
  }
  double stageResolutionDeg() const {
    return 1.0 / truth.at("acquisition").at("steps_per_deg").get<double>();
  }
};

std::vector<std::string> withPoses(std::vector<std::string> args,
                                   const std::vector<std::string>& poses) {
  args.insert(args.end(), poses.begin(), poses.end());
  return args;
}

std::string machineText() {
  utsname u{};
  uname(&u);
  std::string cpu = "unknown CPU";
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);) {
    if (line.rfind("model name", 0) == 0) {
      cpu = line.substr(line.find(':') + 2);
      break;
    }
  }
  return cpu + ", " + std::to_string(std::thread::hardware_concurrency()) + " logical cores, " +
         u.sysname + " " + u.release + " " + u.machine;
}

// The per-point errors of the clouds drawn in the figures.
struct FigureClouds {
  std::string scene;
  std::vector<std::pair<std::string, CloudErrors>> methods;  // label, errors
};

class Study {
 public:
  Study(const StudyRequest& request, StepRunner& runner)
      : request_(request), runner_(runner), work_(fs::path(request.out) / "work") {
    fs::create_directories(work_ / "clouds");
  }

  json run(const StudyDataset& data) {
    data_ = &data;
    firmware::Stopwatch watch;
    json stereo = runner_.run(
        "calibrate-stereo", {"calibrate-stereo", "--board", (data.dir / "board").string(), "--out",
                             (work_ / "stereo.yaml").string()});
    methods_.push_back(
        quasi("paper", "paper's method (high phase)", "high", work_ / "stereo.yaml"));
    methods_.push_back(quasi("ours", "ours (fused phase)", "fused", work_ / "stereo.yaml"));
    json refine;
    if (!request_.no_refine) {
      refine = runner_.run("refine-stereo",
                           withPoses({"refine-stereo", "--stereo", (work_ / "stereo.yaml").string(),
                                      "--board", (data.dir / "board").string(), "--truth",
                                      (data.dir / "stereo_truth.yaml").string(), "--out",
                                      (work_ / "refined.yaml").string()},
                                     data.calib_poses));
      methods_.push_back(
          quasi("refined", "refined stereo + fused phase", "fused", work_ / "refined.yaml"));
    }
    Method sv;
    sv.key = "sv";
    sv.label = "SV (phase stereo, high phase)";
    sv.stereo = true;
    sv.file = work_ / "stereo.yaml";
    methods_.push_back(std::move(sv));
    const double calibrate_s = watch.lapMs() / 1000;

    for (const auto& scene : data.index.sphereScenes())
      measure(scene, "sphere");
    for (const auto& scene : data.index.planeScenes())
      measure(scene, "plane");
    if (data.hasScene("objects")) fringeOrders("objects");
    const double measure_s = watch.lapMs() / 1000;

    json results = {{"stereo", stereo},
                    {"refine", refine},
                    {"methods", json::object()},
                    {"method_order", json::array()}};
    for (const Method& m : methods_) {
      results["method_order"].push_back(m.key);
      results["methods"][m.key] = summary(m);
    }
    results["figures"] = drawFigures();
    results["timings_s"] = {{"calibrations", calibrate_s}, {"reconstructions", measure_s}};
    results["steps_run"] = runner_.stepsRun();
    return results;
  }

 private:
  Method quasi(const std::string& key, const std::string& label, const std::string& phase,
               const fs::path& stereo) {
    Method m;
    m.key = key;
    m.label = label;
    m.file = work_ / ("calib_" + key + ".qcal");
    m.calibration =
        runner_.run("calibrate-" + key, withPoses({"calibrate", "--phase", phase, "--stereo",
                                                   stereo.string(), "--out", m.file.string()},
                                                  data_->calib_poses));
    return m;
  }

  fs::path reconstruct(const Method& m, const std::string& scene) {
    fs::path ply = work_ / "clouds" / (m.key + "_" + scene + ".ply");
    std::vector<std::string> args{"reconstruct", "--out", ply.string()};
    if (m.stereo) {
      args.insert(args.end(), {"--method", "stereo", "--phase", "high", "--stereo"});
    } else {
      args.push_back("--calib");
    }
    args.push_back(m.file.string());
    args.push_back(data_->bundle(scene).string());
    runner_.run("reconstruct-" + m.key + "-" + scene, args);
    return ply;
  }

  void measure(const std::string& scene, const std::string& shape) {
    for (Method& m : methods_) {
      const fs::path ply = reconstruct(m, scene);
      std::vector<std::string> args{"evaluate", shape};
      if (shape == "sphere") args.insert(args.end(), {"--radius", "50"});
      args.insert(args.end(), {"--truth", (data_->dir / "truth.json").string(), "--scene", scene,
                               ply.string()});
      m.evaluations[scene] = runner_.run("evaluate-" + m.key + "-" + scene, args);
      if (isFigureScene(scene) && m.key != "refined") {
        figureFor(scene).methods.emplace_back(
            m.label, cloudErrors(ply,
                                 SceneTruth::fromJson(data_->truth["scenes"][scene],
                                                      data_->dir / "truth.json", scene),
                                 data_->grid));
      }
      release(ply);
    }
  }

  // Points of an isolated-objects scene farther than a few mm from every true
  // surface: a wrong fringe order moves a point by a whole period (~250 mm).
  void fringeOrders(const std::string& scene) {
    const SceneTruth truth =
        SceneTruth::fromJson(data_->truth["scenes"][scene], data_->dir / "truth.json", scene);
    for (Method& m : methods_) {
      if (m.stereo) continue;  // the objects scene is main-only
      const fs::path ply = reconstruct(m, scene);
      const CloudErrors e = cloudErrors(ply, truth, data_->grid);
      double worst = 0;
      for (double d : e.values_mm)
        worst = std::max(worst, std::abs(d));
      m.fringe_orders = {{"scene", scene},
                         {"points", e.values_mm.size()},
                         {"threshold_mm", kFringeOrderThresholdMm},
                         {"errors", countFarther(e.values_mm, kFringeOrderThresholdMm)},
                         {"max_distance_mm", worst}};
      release(ply);
    }
  }

  void release(const fs::path& ply) const {
    if (!request_.keep_clouds) fs::remove(ply);
  }

  // One sphere and one plane are drawn: the first repetition of each first
  // fixed pose (centred sphere at 600 mm, plane at 580 mm).
  bool isFigureScene(const std::string& scene) const {
    return scene == data_->index.sphere_repeats.front().front() ||
           scene == data_->index.plane_repeats.front().front();
  }

  FigureClouds& figureFor(const std::string& scene) {
    for (auto& f : figures_) {
      if (f.scene == scene) return f;
    }
    figures_.push_back({scene, {}});
    return figures_.back();
  }

  json summary(const Method& m) const {
    const StudyIndex& index = data_->index;
    json out = {{"label", m.label},
                {"kind", m.stereo ? "stereo" : "quasi"},
                {"plane_reproducibility", planeReproducibility(m.evaluations, index)},
                {"plane_repeatability", planeRepeatability(m.evaluations, index)},
                {"sphere_reproducibility", sphereReproducibility(m.evaluations, index)},
                {"sphere_repeatability", sphereRepeatability(m.evaluations, index)}};
    if (!m.fringe_orders.is_null()) out["fringe_orders"] = m.fringe_orders;
    if (m.stereo) return out;
    const json& c = m.calibration;
    std::vector<double> pose_rmse;
    for (const json& p : c.at("poses"))
      pose_rmse.push_back(p.at("rmse_mm").get<double>());
    std::sort(pose_rmse.begin(), pose_rmse.end());
    const std::size_t n = pose_rmse.size();
    out["calibration"] = {{"pooled_rmse_mm", c.at("pooled_rmse_mm")},
                          {"sensitivity_mm_per_rad", c.at("sensitivity_mm_per_rad")},
                          {"valid_fraction", c.at("valid_fraction")},
                          {"poses", n},
                          {"pose_rmse_min_mm", pose_rmse.front()},
                          {"pose_rmse_max_mm", pose_rmse.back()},
                          {"pose_rmse_median_mm", (pose_rmse[(n - 1) / 2] + pose_rmse[n / 2]) / 2}};
    BudgetSources sources;
    sources.period_deg = data_->period_deg;
    sources.stage_resolution_deg = data_->stageResolutionDeg();
    out["budget"] = uncertaintyBudget(out["sphere_repeatability"], out["sphere_reproducibility"],
                                      out["calibration"], sources);
    sources.reference_tolerance_mm = kPaperSphereTolerance;
    out["budget_paper_reference"] = uncertaintyBudget(
        out["sphere_repeatability"], out["sphere_reproducibility"], out["calibration"], sources);
    return out;
  }

  json drawFigures() const {
    json files = json::array();
    const cv::Scalar colours[] = {{40, 40, 200}, {180, 90, 20}, {40, 150, 40}};
    for (const FigureClouds& f : figures_) {
      const std::string shape =
          data_->truth["scenes"][f.scene].value("type", "") == "sphere" ? "sphere" : "plane";
      std::vector<ErrorMapPanel> panels;
      std::vector<HistogramSeries> series;
      for (std::size_t i = 0; i < f.methods.size(); ++i) {
        const auto& [label, errors] = f.methods[i];
        panels.push_back({label, errors.map_mm});
        series.push_back({label, errors.values_mm, colours[i % 3]});
      }
      const double scale = symmetricScale(panels);
      const std::string map_file = "error_map_" + shape + ".png";
      const std::string hist_file = "histogram_" + shape + ".png";
      formats::writePng(
          fs::path(request_.out) / map_file,
          drawErrorMaps(panels, scale,
                        "Error against the true " + shape + " (" + f.scene + "), fixed scale"));
      formats::writePng(fs::path(request_.out) / hist_file,
                        drawHistograms(series, scale, 60, "Error histogram, " + f.scene,
                                       "signed distance to the true " + shape + " (mm)"));
      files.push_back({{"scene", f.scene},
                       {"shape", shape},
                       {"error_map", map_file},
                       {"histogram", hist_file},
                       {"scale_mm", scale}});
    }
    return files;
  }

  static constexpr double kPaperSphereTolerance = 0.051;

  const StudyRequest& request_;
  StepRunner& runner_;
  fs::path work_;
  const StudyDataset* data_ = nullptr;
  std::vector<Method> methods_;
  std::vector<FigureClouds> figures_;
};

json simulate(const StudyRequest& request, StepRunner& runner, const fs::path& dir) {
  std::vector<std::string> args{"simulate",
                                "--out",
                                dir.string(),
                                "--boards",
                                std::to_string(request.boards),
                                "--sphere-poses",
                                std::to_string(request.sphere_poses),
                                "--plane-poses",
                                std::to_string(request.plane_poses),
                                "--repeats",
                                std::to_string(request.repeats),
                                "--seed",
                                std::to_string(request.seed)};
  if (request.width > 0) {
    args.insert(args.end(), {"--width", std::to_string(request.width), "--height",
                             std::to_string(request.height)});
  } else if (request.quick) {
    args.push_back("--quick");
  }
  return runner.run("simulate", args);
}

// Rewrites report.md from the results.json of an earlier run.
void rewriteReport(const StudyRequest& request) {
  const fs::path out(request.out);
  json results = formats::readJsonFile(out / "results.json", 64u << 20);
  results["acceptance"] = acceptanceChecks(results);
  formats::writeFileAtomically(out / "results.json", results.dump(2) + "\n");
  formats::writeFileAtomically(out / "report.md", studyReport(results));
  if (request.json) std::cout << results.dump() << "\n";
}

void runStudy(const StudyRequest& request) {
  if (request.report_only) return rewriteReport(request);
  firmware::Stopwatch total;
  if ((request.width == 0) != (request.height == 0))
    throw std::invalid_argument("study: give both --width and --height");
  const fs::path out(request.out);
  fs::create_directories(out);
  StepRunner runner(selfExecutable(), out / "work" / "logs");
  json simulated;
  fs::path dataset_dir = request.dataset;
  if (request.dataset.empty()) {
    dataset_dir = out / "dataset";
    simulated = simulate(request, runner, dataset_dir);
  }
  const StudyDataset data = StudyDataset::open(dataset_dir);
  Study study(request, runner);
  json results = study.run(data);
  const json& acquisition = data.truth.at("acquisition");
  results["dataset"] = {{"dir", dataset_dir.string()},
                        {"simulated_here", !simulated.is_null()},
                        {"simulate", simulated},
                        {"width", data.grid.width},
                        {"height", data.grid.height},
                        {"frames", acquisition.at("frames")},
                        {"noise_scale", acquisition.at("noise_scale")},
                        {"seed", acquisition.at("seed")},
                        {"steps_per_deg", acquisition.at("steps_per_deg")},
                        {"period_deg", data.period_deg},
                        {"calib_poses", data.calib_poses.size()},
                        {"sphere_poses", data.index.sphere_poses.size()},
                        {"plane_poses", data.index.plane_poses.size()},
                        {"repeats", data.index.sphere_repeats.front().size()}};
  results["machine"] = machineText();
  results["acceptance"] = acceptanceChecks(results);
  results["seconds"] = total.elapsedMs() / 1000;
  formats::writeFileAtomically(out / "results.json", results.dump(2) + "\n");
  formats::writeFileAtomically(out / "report.md", studyReport(results));
  if (request.json) {
    std::cout << results.dump() << "\n";
  } else {
    std::cout << "study: " << results["steps_run"].get<int>() << " steps in " << std::fixed
              << std::setprecision(1) << results["seconds"].get<double>() << " s -> "
              << (out / "report.md").string() << "\n";
    for (const json& c : results["acceptance"]) {
      std::cout << "  " << (c.at("pass").get<bool>() ? "PASS" : "FAIL") << "  "
                << c.at("check").get<std::string>() << ": " << c.at("measured").get<std::string>()
                << "\n";
    }
  }
}

}  // namespace

void addStudyCommand(CLI::App& app) {
  auto request = std::make_shared<StudyRequest>();
  CLI::App* cmd = app.add_subcommand(
      "study", "the paper's experiments on the virtual head: report.md, results.json, figures");
  cmd->add_option("--out", request->out, "output directory")->required();
  cmd->add_option("--dataset", request->dataset,
                  "a dataset simulated with study scenes (default: simulate one into OUT/dataset)");
  cmd->add_flag("--quick", request->quick, "320x256 and small counts (3 poses, 3 repeats)");
  cmd->add_option("--width", request->width, "image width of the simulated dataset")
      ->check(CLI::Range(64, 4096));
  cmd->add_option("--height", request->height, "image height")->check(CLI::Range(64, 4096));
  auto* boards =
      cmd->add_option("--boards", request->boards, "checkerboard poses (default 64, --quick 40)")
          ->check(CLI::Range(6, 99));
  auto* spheres =
      cmd->add_option("--sphere-poses", request->sphere_poses, "sphere poses (default 10)")
          ->check(CLI::Range(2, 99));
  auto* planes = cmd->add_option("--plane-poses", request->plane_poses, "plane poses (default 10)")
                     ->check(CLI::Range(2, 99));
  auto* repeats =
      cmd->add_option("--repeats", request->repeats, "repeated scans of 2 fixed poses (default 5)")
          ->check(CLI::Range(2, 99));
  cmd->add_option("--seed", request->seed, "noise seed of the simulated dataset");
  cmd->add_flag("--no-refine", request->no_refine, "skip the refine-stereo variant");
  cmd->add_flag("--keep-clouds", request->keep_clouds,
                "keep every reconstructed cloud in OUT/work/clouds");
  cmd->add_flag("--report-only", request->report_only,
                "only rewrite OUT/report.md from OUT/results.json of an earlier run");
  cmd->add_flag("--json", request->json, "print all the numbers as one JSON object");
  cmd->callback([request, boards, spheres, planes, repeats] {
    if (request->quick) {
      if (boards->count() == 0) request->boards = 40;
      if (spheres->count() == 0) request->sphere_poses = 3;
      if (planes->count() == 0) request->plane_poses = 3;
      if (repeats->count() == 0) request->repeats = 3;
    }
    runStudy(*request);
  });
}

}  // namespace cylscan::tools
