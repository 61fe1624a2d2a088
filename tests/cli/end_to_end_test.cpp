// SPDX-License-Identifier: Apache-2.0
// The whole chain as a user runs it, on the virtual head at 320×256:
// simulate → calibrate-stereo → calibrate → reconstruct → evaluate, checked
// against the simulator's truth (stereo_truth.yaml, truth.json).
//
// Bounds, for this reduced resolution (f ≈ 1113 px, 1/3.1 of the paper's):
// - stereo RMS reprojection < 0.5 px: corners of a rendered board are good
//   to ~0.1 px; 0.5 px would mean misdetections.
// - focal lengths within 1 % of the truth: with 64 boards (the paper's count)
//   cv::calibrateCamera's own σ(fx) is ~0.2 %.
// - pooled calibration RMSE < 0.1 mm: the residual is the depth noise of one
//   pixel's phase (σΦ of a few mrad × S_eff ≈ 41 mm/rad) plus the cubic's
//   model error; the paper reports 0.085 mm at full resolution.
// - sphere radius within 0.3 mm of 50 and reference-sphere RMSE < 0.2 mm:
//   the paper's quasi method has 0.35 mm RMSE on a real ball; the virtual
//   one has no projector distortion beyond the simulated optics.
// - points vs the true sphere / plane: RMS < 1 mm, centre within 1.5 mm.
//   The absolute placement inherits the stereo calibration's error (σ(fx)
//   ≈ 0.2 % is ~1.2 mm of depth at 580 mm), which the quasi-calibration can
//   only copy, not correct.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "algo/quasi_calibration.hpp"
#include "cli_support.hpp"
#include "formats/point_cloud.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json parseJson(const ToolResult& run) {
  try {
    return json::parse(run.output);
  } catch (const json::exception&) {
    ADD_FAILURE() << "not one JSON object:\n" << run.output;
    return json::object();
  }
}

Eigen::Vector3d vec(const json& v) {
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

struct DistanceStats {
  double mean = 0, rms = 0, max_abs = 0;
  std::size_t count = 0;
};

// Signed distances of a cloud's points to a truth surface (sphere or plane).
DistanceStats distancesToTruth(const fs::path& ply, const json& truth) {
  const formats::PointCloud cloud = formats::readPly(ply);
  DistanceStats s;
  double sum = 0, sum2 = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    double d = 0;
    if (truth.at("type") == "sphere") {
      d = (p - vec(truth.at("center"))).norm() - truth.at("radius").get<double>();
    } else {
      d = vec(truth.at("normal")).normalized().dot(p - vec(truth.at("point")));
    }
    sum += d;
    sum2 += d * d;
    s.max_abs = std::max(s.max_abs, std::abs(d));
  }
  s.count = cloud.size();
  s.mean = s.count ? sum / static_cast<double>(s.count) : NAN;
  s.rms = s.count ? std::sqrt(sum2 / static_cast<double>(s.count)) : NAN;
  return s;
}

void expectFocalWithin(const cv::Matx33d& estimated, const cv::Matx33d& truth, double tolerance,
                       const std::string& camera) {
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(estimated(i, i) / truth(i, i), 1.0, tolerance)
        << camera << (i == 0 ? " fx " : " fy ") << estimated(i, i) << " vs " << truth(i, i);
  }
}

class EndToEnd : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<TempDir>();
    const auto run =
        runTool("simulate --json --width 320 --height 256 --boards 64 --out " + data().string());
    simulated_ = run.exit_code == 0;
    if (!simulated_) std::cerr << "simulate failed:\n" << run.output << "\n";
  }
  static void TearDownTestSuite() { dir_.reset(); }
  void SetUp() override { ASSERT_TRUE(simulated_) << "cylscan simulate failed"; }

  static fs::path data() { return dir_->path() / "data"; }
  static fs::path out(const std::string& name) { return dir_->path() / name; }
  static json truth() { return json::parse(std::ifstream(data() / "truth.json")); }

  static std::string calibPoses() {
    std::vector<std::string> poses;
    for (const auto& entry : fs::directory_iterator(data() / "calib")) {
      if (entry.is_directory()) poses.push_back(entry.path().string());
    }
    std::sort(poses.begin(), poses.end());
    std::string args;
    for (const auto& p : poses)
      args += " " + p;
    return args;
  }

  // The steps, each once for the suite (tests run in declaration order).
  static json calibrateStereo() {
    const auto run = runTool("calibrate-stereo --json --board " + (data() / "board").string() +
                             " --out " + out("stereo.yaml").string());
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return parseJson(run);
  }
  static json calibrate() {
    const auto run = runTool("calibrate --json --stereo " + out("stereo.yaml").string() +
                             " --out " + out("calib.qcal").string() + calibPoses());
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return parseJson(run);
  }
  static json reconstruct(const fs::path& bundle, const fs::path& ply,
                          const std::string& method = "quasi") {
    const std::string source = method == "quasi"
                                   ? " --calib " + out("calib.qcal").string()
                                   : " --method stereo --stereo " + out("stereo.yaml").string();
    const auto run =
        runTool("reconstruct --json" + source + " --out " + ply.string() + " " + bundle.string());
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return parseJson(run);
  }
  static json evaluate(const std::string& shape, const fs::path& ply) {
    const auto run = runTool("evaluate " + shape + " --json " + ply.string());
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return parseJson(run);
  }

  // The checks of each step, in the order the chain runs.
  void checkStereoCalibration() {
    const json summary = calibrateStereo();
    std::cout << "[e2e] calibrate-stereo: " << summary.dump() << "\n";
    EXPECT_LT(summary.at("stereo_rms_px").get<double>(), 0.5);
    EXPECT_LT(summary.at("main").at("rms_px").get<double>(), 0.5);
    EXPECT_LT(summary.at("aux").at("rms_px").get<double>(), 0.5);
    const auto estimated = formats::readStereoCalibration(out("stereo.yaml"));
    const auto truth = formats::readStereoCalibration(data() / "stereo_truth.yaml");
    expectFocalWithin(estimated.camera_matrix_main, truth.camera_matrix_main, 0.01, "main");
    expectFocalWithin(estimated.camera_matrix_aux, truth.camera_matrix_aux, 0.01, "aux");
    EXPECT_NEAR(cv::norm(estimated.T) / cv::norm(truth.T), 1.0, 0.01);
    checkJointRefinement(summary);
  }

  // --refine-jointly writes intrinsics that stereoCalibrate moved, so the RMS
  // it prints per camera must be theirs: the root mean square of its pairs'
  // reprojection errors (which the joint fit gives per view), and the stereo
  // RMS their mean square. The separate fits' RMS differs from it.
  void checkJointRefinement(const json& separate) {
    const auto run =
        runTool("calibrate-stereo --json --refine-jointly --board " + (data() / "board").string() +
                " --out " + out("stereo_joint.yaml").string());
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const json joint = parseJson(run);
    EXPECT_EQ(joint.at("refinement"), "joint");
    double main_sq = 0, aux_sq = 0;
    for (const json& view : joint.at("views")) {
      main_sq += std::pow(view.at("main_rms_px").get<double>(), 2);
      aux_sq += std::pow(view.at("aux_rms_px").get<double>(), 2);
    }
    const auto n = static_cast<double>(joint.at("views").size());
    ASSERT_GT(n, 0);
    const double main_rms = joint.at("main").at("rms_px").get<double>();
    const double aux_rms = joint.at("aux").at("rms_px").get<double>();
    EXPECT_NEAR(main_rms, std::sqrt(main_sq / n), 1e-9 * main_rms);
    EXPECT_NEAR(aux_rms, std::sqrt(aux_sq / n), 1e-9 * aux_rms);
    // The joint fit's RMS over both cameras' points (equal counts per pair).
    EXPECT_NEAR(joint.at("stereo_rms_px").get<double>(), std::sqrt((main_sq + aux_sq) / (2 * n)),
                1e-6);
    EXPECT_NE(main_rms, separate.at("main").at("rms_px").get<double>());
    std::cout << "[e2e] calibrate-stereo --refine-jointly: main " << main_rms << " px, aux "
              << aux_rms << " px (separate fits " << separate.at("main").at("rms_px") << ", "
              << separate.at("aux").at("rms_px") << ")\n";
  }

  void checkQuasiCalibration() {
    ASSERT_TRUE(fs::exists(out("stereo.yaml")));
    const json summary = calibrate();
    std::cout << "[e2e] calibrate: pooled " << summary.value("pooled_rmse_mm", -1.0)
              << " mm, valid " << summary.value("valid_fraction", -1.0) << ", S_eff "
              << summary.value("sensitivity_mm_per_rad", -1.0) << " mm/rad, "
              << summary.value("timings_ms", json::object()).dump() << "\n";
    EXPECT_LT(summary.at("pooled_rmse_mm").get<double>(), 0.1);
    EXPECT_GT(summary.at("valid_fraction").get<double>(), 0.95);
    // The file records the centre its poses' orders were numbered about: the
    // first pose's, and every pose measured its own within a small spread of it.
    ASSERT_TRUE(summary.at("order_centre_rad").is_number()) << summary.dump();
    const double centre = summary.at("order_centre_rad").get<double>();
    std::ifstream qcal(out("calib.qcal"), std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(qcal)), {});
    EXPECT_NEAR(algo::QuasiCalibration::deserialize(std::as_bytes(std::span(bytes)))
                    .info()
                    .order_centre_rad,
                centre, 1e-6);
    for (const auto& pose : summary.at("poses")) {
      const json& residual = pose.at("order_residual");
      EXPECT_GT(residual.at("samples").get<int>(), 0) << pose.dump();
      EXPECT_LT(std::abs(residual.at("centre_rad").get<double>() - centre), 0.2) << pose.dump();
      EXPECT_LT(pose.at("rmse_mm").get<double>(), 0.15) << pose.dump();
      EXPECT_LT(pose.at("plane_fit_rmse_mm").get<double>(), 0.15) << pose.dump();
    }
  }

  void checkSpheres() {
    ASSERT_TRUE(fs::exists(out("calib.qcal")));
    int spheres = 0;
    const json scenes = truth().at("scenes");
    for (const auto& [scene, t] : scenes.items()) {
      if (t.at("type") != "sphere") continue;
      ++spheres;
      const fs::path ply = out(scene + ".ply");
      const json rec = reconstruct(data() / "test" / scene, ply);
      const json ev = evaluate("sphere --radius 50", ply);
      const DistanceStats d = distancesToTruth(ply, t);
      std::cout << "[e2e] " << scene << ": " << rec.value("points", 0) << " points, radius "
                << ev.at("free").at("radius_mm") << ", RMSE " << ev.at("reference").at("rmse_mm")
                << ", vs truth mean " << d.mean << " rms " << d.rms << " max " << d.max_abs << "\n";
      EXPECT_GT(d.count, 5000u) << scene;
      EXPECT_NEAR(ev.at("free").at("radius_mm").get<double>(), t.at("radius").get<double>(), 0.3)
          << scene;
      EXPECT_LT(ev.at("reference").at("rmse_mm").get<double>(), 0.2) << scene;
      EXPECT_LT(d.rms, 1.0) << scene;
      EXPECT_LT((vec(ev.at("free").at("centre")) - vec(t.at("center"))).norm(), 1.5) << scene;
    }
    EXPECT_GE(spheres, 1);
  }

  // evaluate --truth measures the same distances as this test's own code.
  void checkTruthComparison() {
    const json t = truth().at("scenes").at("sphere_1");
    const fs::path ply = out("sphere_1.ply");
    ASSERT_TRUE(fs::exists(ply));
    const json ev = evaluate(
        "sphere --radius 50 --truth " + (data() / "truth.json").string() + " --scene sphere_1",
        ply);
    const DistanceStats d = distancesToTruth(ply, t);
    EXPECT_NEAR(ev.at("truth").at("rmse_mm").get<double>(), d.rms, 1e-6);
    EXPECT_NEAR(ev.at("truth").at("mean_mm").get<double>(), d.mean, 1e-6);
    const Eigen::Vector3d offset = vec(ev.at("free").at("centre")) - vec(t.at("center"));
    EXPECT_NEAR((vec(ev.at("truth").at("centre_offset_mm")) - offset).norm(), 0.0, 1e-9);
    const auto missing =
        runTool("evaluate sphere --radius 50 --truth " + (data() / "truth.json").string() +
                " --scene nope " + ply.string());
    EXPECT_EQ(missing.exit_code, 2);
    EXPECT_NE(missing.output.find("no scene 'nope'"), std::string::npos) << missing.output;
  }

  // refine-stereo makes the pair consistent with the phase of the plane
  // poses: the equal-phase residual falls, the checkerboards stay as well fitted.
  void checkRefinedStereo() {
    const auto run = runTool(
        "refine-stereo --json --samples 800 --stereo " + out("stereo.yaml").string() + " --board " +
        (data() / "board").string() + " --truth " + (data() / "stereo_truth.yaml").string() +
        " --out " + out("refined.yaml").string() + calibPoses());
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const json s = parseJson(run);
    std::cout << "[e2e] refine-stereo: before " << s.at("before").dump() << " after "
              << s.at("after").dump() << " truth " << s.at("truth").dump() << "\n";
    EXPECT_LT(s.at("after").at("phase_rms_px").get<double>(),
              0.9 * s.at("before").at("phase_rms_px").get<double>());
    EXPECT_LT(s.at("after").at("board_aux_rms_px").get<double>(),
              1.05 * s.at("before").at("board_aux_rms_px").get<double>());
    EXPECT_LT(s.at("after").at("board_main_rms_px").get<double>(),
              1.05 * s.at("before").at("board_main_rms_px").get<double>());
    const auto refined = formats::readStereoCalibration(out("refined.yaml"));
    const auto truth_file = formats::readStereoCalibration(data() / "stereo_truth.yaml");
    expectFocalWithin(refined.camera_matrix_main, truth_file.camera_matrix_main, 0.01, "main");
    EXPECT_NEAR(cv::norm(refined.T) / cv::norm(truth_file.T), 1.0, 0.01);
  }

  void checkPlane() {
    ASSERT_TRUE(fs::exists(out("calib.qcal")));
    const json t = truth().at("scenes").at("plane");
    const fs::path ply = out("plane.ply");
    reconstruct(data() / "test" / "plane", ply);
    const json ev = evaluate("plane", ply);
    const DistanceStats d = distancesToTruth(ply, t);
    const double cos_angle = std::abs(vec(ev.at("plane").at("normal")).dot(vec(t.at("normal"))));
    std::cout << "[e2e] plane: RMSE " << ev.at("rmse_mm") << ", regional "
              << ev.value("regional", json::object()).dump() << ", vs truth mean " << d.mean
              << " rms " << d.rms << ", normal off by "
              << std::acos(std::min(1.0, cos_angle)) * 180 / std::numbers::pi << " deg\n";
    EXPECT_LT(ev.at("rmse_mm").get<double>(), 0.15);
    EXPECT_LT(d.rms, 1.0);
    EXPECT_GT(cos_angle, std::cos(0.3 * std::numbers::pi / 180.0));
  }

  void checkStereoMethod() {
    ASSERT_TRUE(fs::exists(out("calib.qcal")));
    const json truth_calib = truth().at("calib");
    const std::string pose = truth_calib.begin().key();
    const fs::path bundle = data() / "calib" / pose;
    reconstruct(bundle, out("sv.ply"), "stereo");
    reconstruct(bundle, out("quasi.ply"), "quasi");
    const json sv = evaluate("plane", out("sv.ply"));
    const json quasi = evaluate("plane", out("quasi.ply"));
    const DistanceStats dsv = distancesToTruth(out("sv.ply"), truth_calib.at(pose));
    const DistanceStats dq = distancesToTruth(out("quasi.ply"), truth_calib.at(pose));
    std::cout << "[e2e] " << pose << ": plane RMSE stereo " << sv.at("rmse_mm") << " ("
              << sv.at("points") << " points), quasi " << quasi.at("rmse_mm") << " ("
              << quasi.at("points") << " points); vs truth rms stereo " << dsv.rms << ", quasi "
              << dq.rms << "\n";
    EXPECT_LT(sv.at("rmse_mm").get<double>(), 0.15);
    EXPECT_LT(quasi.at("rmse_mm").get<double>(), 0.15);
    EXPECT_LT(dsv.rms, 1.0);
    EXPECT_LT(dq.rms, 1.0);
  }

  static std::unique_ptr<TempDir> dir_;
  static bool simulated_;
};

std::unique_ptr<TempDir> EndToEnd::dir_;
bool EndToEnd::simulated_ = false;

// One test: the steps depend on each other's files, and CTest runs every
// test in a process of its own.
TEST_F(EndToEnd, SimulateCalibrateReconstructEvaluate) {
  {
    SCOPED_TRACE("calibrate-stereo");
    checkStereoCalibration();
  }
  ASSERT_TRUE(fs::exists(out("stereo.yaml")));
  {
    SCOPED_TRACE("calibrate");
    checkQuasiCalibration();
  }
  ASSERT_TRUE(fs::exists(out("calib.qcal")));
  {
    SCOPED_TRACE("spheres");
    checkSpheres();
  }
  {
    SCOPED_TRACE("evaluate against truth");
    checkTruthComparison();
  }
  {
    SCOPED_TRACE("plane");
    checkPlane();
  }
  {
    SCOPED_TRACE("refine-stereo");
    checkRefinedStereo();
  }
  {
    SCOPED_TRACE("stereo method");
    checkStereoMethod();
  }
}

}  // namespace
}  // namespace cylscan::test
