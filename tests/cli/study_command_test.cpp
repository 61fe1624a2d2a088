// SPDX-License-Identifier: Apache-2.0
// `cylscan study` as a user runs it: a tiny study at 320×256 (2 poses of each,
// 2 repetitions, no refine-stereo), its report and figures, its numbers
// checked against `evaluate --truth` run separately on the same clouds, and
// the uncertainty budget's arithmetic; and the simulate flags behind it.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli_support.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

json lastJsonLine(const ToolResult& run) {
  std::istringstream lines(run.output);
  std::string line, last;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.front() == '{') last = line;
  }
  try {
    return json::parse(last);
  } catch (const json::exception&) {
    ADD_FAILURE() << "no JSON object in:\n" << run.output;
    return json::object();
  }
}

class StudyCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<TempDir>();
    const auto run = runTool(
        "study --quick --sphere-poses 2 --plane-poses 2 --repeats 2 --no-refine --keep-clouds "
        "--json --out " +
        out().string());
    ran_ = run.exit_code == 0;
    if (!ran_) std::cerr << "study failed:\n" << run.output << "\n";
    results_ = std::make_unique<json>(ran_ ? lastJsonLine(run) : json::object());
  }
  static void TearDownTestSuite() {
    results_.reset();
    dir_.reset();
  }
  void SetUp() override { ASSERT_TRUE(ran_) << "cylscan study failed"; }

  static fs::path out() { return dir_->path() / "study"; }
  static const json& results() { return *results_; }
  static fs::path cloud(const std::string& method, const std::string& scene) {
    return out() / "work" / "clouds" / (method + "_" + scene + ".ply");
  }
  static json evaluate(const std::string& shape, const std::string& method,
                       const std::string& scene) {
    const auto run = runTool("evaluate " + shape + " --json --truth " +
                             (out() / "dataset" / "truth.json").string() + " --scene " + scene +
                             " " + cloud(method, scene).string());
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return lastJsonLine(run);
  }

  void checkReportAndFigures() {
    const std::string report = readText(out() / "report.md");
    for (const char* section :
         {"## Acceptance checks", "## Calibration residual", "## Plane reproducibility",
          "## Plane repeatability", "## Sphere reproducibility", "## Sphere repeatability",
          "## Uncertainty budget", "## Regional RMSE along u", "## Against the true surfaces"}) {
      EXPECT_NE(report.find(section), std::string::npos) << section;
    }
    // The paper's published figures stand beside the measurements.
    EXPECT_NE(report.find("0.215"), std::string::npos);  // its expanded uncertainty
    EXPECT_NE(report.find("0.346"), std::string::npos);  // its mean sphere RMSE
    ASSERT_EQ(results().at("figures").size(), 2u);
    for (const json& f : results().at("figures")) {
      for (const char* key : {"error_map", "histogram"}) {
        const std::string file = f.at(key).get<std::string>();
        const cv::Mat image = cv::imread((out() / file).string(), cv::IMREAD_UNCHANGED);
        EXPECT_FALSE(image.empty()) << file;
        EXPECT_EQ(image.channels(), 3) << file;
        EXPECT_NE(report.find("](" + file + ")"), std::string::npos) << file;
      }
    }
    const json on_disk = json::parse(readText(out() / "results.json"));
    EXPECT_EQ(on_disk.at("methods"), results().at("methods"));
  }

  void checkSphereNumbers() {
    for (const std::string method : {"paper", "ours", "sv"}) {
      const json& table = results().at("methods").at(method).at("sphere_reproducibility");
      for (const json& pose : table.at("poses")) {
        const std::string scene = pose.at("scene").get<std::string>();
        const json e = evaluate("sphere --radius 50", method, scene);
        EXPECT_DOUBLE_EQ(pose.at("radius").get<double>(), e.at("free").at("radius_mm"));
        EXPECT_DOUBLE_EQ(pose.at("rmse").get<double>(), e.at("reference").at("rmse_mm"));
        EXPECT_DOUBLE_EQ(pose.at("mean").get<double>(), e.at("reference").at("mean_mm"));
        EXPECT_DOUBLE_EQ(pose.at("truth_rmse").get<double>(), e.at("truth").at("rmse_mm"));
      }
      const double a = table.at("poses")[0].at("rmse").get<double>();
      const double b = table.at("poses")[1].at("rmse").get<double>();
      EXPECT_NEAR(table.at("rmse_mean").get<double>(), (a + b) / 2, 1e-12);
      EXPECT_NEAR(table.at("rmse_std").get<double>(), std::abs(a - b) / std::sqrt(2.0), 1e-12);
    }
  }

  void checkPlaneNumbers() {
    for (const std::string method : {"paper", "ours"}) {
      const json& m = results().at("methods").at(method);
      for (const json& pose : m.at("plane_reproducibility").at("poses")) {
        const json e = evaluate("plane", method, pose.at("scene").get<std::string>());
        EXPECT_DOUBLE_EQ(pose.at("rmse").get<double>(), e.at("rmse_mm"));
        EXPECT_DOUBLE_EQ(pose.at("central").get<double>(), e.at("regional").at("central_rmse_mm"));
        EXPECT_DOUBLE_EQ(pose.at("outer").get<double>(), e.at("regional").at("outer_rmse_mm"));
        EXPECT_DOUBLE_EQ(pose.at("truth_rmse").get<double>(), e.at("truth").at("rmse_mm"));
      }
      for (const json& pose : m.at("plane_repeatability")) {
        ASSERT_EQ(pose.at("repetitions").size(), 2u);
        const json& first = pose.at("repetitions")[0];
        const json e = evaluate("plane", method, first.at("scene").get<std::string>());
        EXPECT_DOUBLE_EQ(first.at("rmse").get<double>(), e.at("rmse_mm"));
      }
    }
  }

  void checkBudget() {
    for (const std::string method : {"paper", "ours"}) {
      const json& m = results().at("methods").at(method);
      for (const char* which : {"budget", "budget_paper_reference"}) {
        const json& b = m.at(which);
        double sum = 0;
        for (const char* u : {"u_rep", "u_repr", "u_ref", "u_cal", "u_stage"})
          sum += std::pow(b.at(u).get<double>(), 2);
        EXPECT_NEAR(b.at("combined").get<double>(), std::sqrt(sum), 1e-12) << which;
        EXPECT_NEAR(b.at("expanded").get<double>(), 2 * std::sqrt(sum), 1e-12) << which;
        EXPECT_DOUBLE_EQ(b.at("u_cal").get<double>(),
                         m.at("calibration").at("pooled_rmse_mm").get<double>());
        const json& repro = m.at("sphere_reproducibility");
        EXPECT_NEAR(b.at("u_repr").get<double>(),
                    repro.at("rmse_std").get<double>() / std::sqrt(2.0), 1e-12);
      }
      EXPECT_EQ(m.at("budget").at("u_ref").get<double>(), 0.0);  // the virtual sphere is exact
      EXPECT_NEAR(m.at("budget_paper_reference").at("u_ref").get<double>(), 0.051 / std::sqrt(3.0),
                  1e-12);
      // u_rep: the larger repeatability STD of the two fixed poses, over √n.
      const json& rep = m.at("sphere_repeatability");
      const double s =
          std::max(rep[0].at("rmse_std").get<double>(), rep[1].at("rmse_std").get<double>());
      EXPECT_NEAR(m.at("budget").at("u_rep").get<double>(), s / std::sqrt(2.0), 1e-12);
    }
  }

  void checkRepeats() {
    for (const std::string method : {"paper", "ours"}) {
      for (const json& pose : results().at("methods").at(method).at("sphere_repeatability")) {
        const json& reps = pose.at("repetitions");
        EXPECT_NE(reps[0].at("rmse").get<double>(), reps[1].at("rmse").get<double>());
        EXPECT_GT(pose.at("rmse_std").get<double>(), 0.0);
      }
    }
  }

  static std::unique_ptr<TempDir> dir_;
  static bool ran_;
  static std::unique_ptr<json> results_;
};

std::unique_ptr<TempDir> StudyCommand::dir_;
bool StudyCommand::ran_ = false;
std::unique_ptr<json> StudyCommand::results_;

// One test: the study runs once (CTest runs every test in a process of its own).
TEST_F(StudyCommand, ReportFiguresNumbersAndBudget) {
  {
    SCOPED_TRACE("checkReportAndFigures");
    checkReportAndFigures();
  }
  {
    SCOPED_TRACE("checkSphereNumbers");
    checkSphereNumbers();
  }
  {
    SCOPED_TRACE("checkPlaneNumbers");
    checkPlaneNumbers();
  }
  {
    SCOPED_TRACE("checkBudget");
    checkBudget();
  }
  {
    SCOPED_TRACE("checkRepeats");
    checkRepeats();
  }
}

// Every regular file under `dir`, relative to it.
std::vector<fs::path> filesUnder(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) files.push_back(fs::relative(e.path(), dir));
  }
  std::sort(files.begin(), files.end());
  return files;
}

// The study flags add scenes after the default ones: every default file keeps
// its bytes; the same seed gives the same bytes again; repetitions of one pose
// carry different noise.
TEST(SimulateStudyScenes, AddScenesWithoutChangingTheDefaultDatasetAndRepeatsDiffer) {
  TempDir dir;
  const std::string base = "simulate --quick --boards 1 --poses 1 --frames 3 --out ";
  const std::string study = " --sphere-poses 1 --plane-poses 2 --repeats 2";
  ASSERT_EQ(runTool(base + (dir.path() / "plain").string()).exit_code, 0);
  ASSERT_EQ(runTool(base + (dir.path() / "a").string() + study).exit_code, 0);
  ASSERT_EQ(runTool(base + (dir.path() / "b").string() + study).exit_code, 0);
  for (const fs::path& f : filesUnder(dir.path() / "plain")) {
    if (f == "truth.json") continue;
    EXPECT_EQ(readText(dir.path() / "plain" / f), readText(dir.path() / "a" / f)) << f;
  }
  const std::vector<fs::path> files = filesUnder(dir.path() / "a");
  EXPECT_EQ(files, filesUnder(dir.path() / "b"));
  for (const fs::path& f : files)
    EXPECT_EQ(readText(dir.path() / "a" / f), readText(dir.path() / "b" / f)) << f;

  const json truth = json::parse(readText(dir.path() / "a" / "truth.json"));
  const json& index = truth.at("study");
  EXPECT_EQ(index.at("sphere_poses").size(), 1u);
  EXPECT_EQ(index.at("plane_poses").size(), 2u);
  ASSERT_EQ(index.at("sphere_repeats").size(), 2u);
  const json plain = json::parse(readText(dir.path() / "plain" / "truth.json"));
  for (const auto& [scene, entry] : plain.at("scenes").items())
    EXPECT_EQ(truth.at("scenes").at(scene), entry) << scene;
  const auto r0 = index.at("sphere_repeats")[0][0].get<std::string>();
  const auto r1 = index.at("sphere_repeats")[0][1].get<std::string>();
  EXPECT_EQ(truth.at("scenes").at(r0), truth.at("scenes").at(r1));  // the same pose
  for (const std::string camera : {"main", "aux"}) {
    const fs::path f = fs::path(camera) / "high";
    const fs::path first = *fs::directory_iterator(dir.path() / "a" / "test" / r0 / f);
    const cv::Mat a = cv::imread(first.string(), cv::IMREAD_UNCHANGED);
    const cv::Mat b = cv::imread((dir.path() / "a" / "test" / r1 / f / first.filename()).string(),
                                 cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(a.empty());
    ASSERT_EQ(a.size(), b.size());
    const double differing = cv::countNonZero(a != b) / static_cast<double>(a.total());
    EXPECT_GT(differing, 0.1) << camera;                                // independent noise
    EXPECT_LT(cv::norm(a, b, cv::NORM_L1) / a.total(), 5.0) << camera;  // the same scene
  }
}

TEST(StudyCommandInput, DirectoryThatIsNotADatasetIsBadInputNamingWhatIsMissing) {
  TempDir dir;
  const auto run =
      runTool("study --dataset " + dir.path().string() + " --out " + (dir.path() / "o").string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find((dir.path() / "truth.json").string()), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("missing"), std::string::npos) << run.output;
}

TEST(StudyCommandInput, DatasetWithoutStudyScenesIsBadInputNamingTruthJson) {
  TempDir dir;
  for (const char* d : {"board", "calib"})
    fs::create_directories(dir.path() / d);
  std::ofstream(dir.path() / "stereo_truth.yaml") << "%YAML:1.0\n";
  std::ofstream(dir.path() / "truth.json") << R"({"scenes": {}, "calib": {}})";
  const auto run =
      runTool("study --dataset " + dir.path().string() + " --out " + (dir.path() / "o").string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("truth.json: has no \"study\" entry"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace cylscan::test
