// SPDX-License-Identifier: Apache-2.0
// The 360° head's extrinsics and merged cloud, end to end on the virtual head
// (the CTest fixture fixture.ring_head, tests/fixtures/ring_head.cmake: four
// per-direction quasi-calibrations made as a user makes them, the turntable
// dataset and a ring scan of the surround scene, 320×256):
//   * calibrate-head on the turntable bundles recovers the true extrinsics;
//   * the merged cloud of the surround scan (head frame): every 50 mm sphere's
//     free-fit radius and centre against the truth, and `cylscan evaluate
//     sphere` reads the merged PLY;
//   * the held-out sphere of turntable/check/, seen by two neighbouring
//     cameras at two turns, mapped to the world with the extrinsics and the
//     known turns, agrees between the cameras.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "algo/head_extrinsics.hpp"
#include "algo/sphere_search.hpp"
#include "algo/surface_fit.hpp"
#include "formats/head_extrinsics.hpp"
#include "formats/point_cloud.hpp"
#include "tests/cli/cli_support.hpp"

namespace cylscan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kFixture = CYLSCAN_RING_FIXTURE;
constexpr double kDeg = std::numbers::pi / 180.0;

json readJson(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

Eigen::Vector3d vec(const json& j) {
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

algo::RigidPose poseOf(const json& j) {
  algo::RigidPose p;
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k)
      p.R(i, k) = j["R"][i][k].get<double>();
    p.T(i) = j["T"][i].get<double>();
  }
  return p;
}

algo::RigidPose poseOf(const formats::CameraPose& c) {
  algo::RigidPose p;
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k)
      p.R(i, k) = c.R[i][k];
    p.T(i) = c.T[i];
  }
  return p;
}

// The points of `cloud` within `reach` of `centre`.
algo::Points3d near(const formats::PointCloud& cloud, const Eigen::Vector3d& centre, double reach) {
  algo::Points3d out;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d x(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    if ((x - centre).norm() < reach) out.push_back(x);
  }
  return out;
}

class RingHead : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(kFixture / "ready")) return;
    work_ = std::make_unique<test::TempDir>();
    std::string bundles;
    for (const auto& entry : fs::directory_iterator(kFixture / "turntable")) {
      if (entry.is_directory() && entry.path().filename().string().starts_with("turn"))
        bundles += " " + entry.path().string();
    }
    const fs::path head = work_->path() / "head.json";
    calibrate_ = std::make_unique<test::ToolResult>(
        test::runTool("calibrate-head --json --calib-dir " + (kFixture / "calib").string() +
                      " --out " + head.string() + bundles));
  }
  static void TearDownTestSuite() {
    calibrate_.reset();
    work_.reset();
  }
  void SetUp() override {
    if (!fs::exists(kFixture / "ready"))
      FAIL() << "no fixture " << kFixture << " (ctest runs fixture.ring_head first)";
    ASSERT_EQ(calibrate_->exit_code, 0) << calibrate_->output;
  }
  static fs::path headFile() { return work_->path() / "head.json"; }

  static std::unique_ptr<test::TempDir> work_;
  static std::unique_ptr<test::ToolResult> calibrate_;
};
std::unique_ptr<test::TempDir> RingHead::work_;
std::unique_ptr<test::ToolResult> RingHead::calibrate_;

TEST_F(RingHead, CalibrateHeadRecoversTheTrueExtrinsics) {
  const json truth = readJson(kFixture / "turntable" / "truth.json");
  const formats::HeadExtrinsics head = formats::readHeadExtrinsics(headFile());
  const json summary = json::parse(calibrate_->output.substr(calibrate_->output.find('{')));
  ASSERT_EQ(head.cameras.size(), truth["head"]["cameras"].size());
  // What limits the poses is not the solver (its residuals are ~0.01 mm) but
  // each direction's own quasi-calibration: at 320×256 its focal lengths come
  // out to ~0.2 % (64 boards), which places a cloud ~600 mm away to ~1 mm —
  // main's own 50 mm sphere of the surround scan (identity pose) is off the
  // truth by 0.78 mm (MergedSurroundCloudPlacesEverySphere). A pose relates two
  // such frames, so it is off by up to ~2 mm, and over the target's ~80 mm
  // by up to ~2/40 rad… in practice ≤ 0.1°. Bounds: 2 mm, 0.25°.
  // Measured: rotation 0.065–0.104°, translation 0.77–1.12 mm.
  for (const auto& [camera, pose_json] : truth["head"]["cameras"].items()) {
    SCOPED_TRACE(camera);
    ASSERT_TRUE(head.hasCamera(camera));
    const algo::RigidPose want = poseOf(pose_json);
    const algo::RigidPose got = poseOf(head.pose(camera));
    const double angle = Eigen::AngleAxisd(want.R.transpose() * got.R).angle() / kDeg;
    const double shift = (want.T - got.T).norm();
    std::cout << "[ figures  ] " << camera << ": rotation error " << angle
              << "°, translation error " << shift << " mm, residual rms "
              << summary["cameras"][camera]["rms_mm"] << " mm\n";
    EXPECT_LT(angle, 0.25);
    EXPECT_LT(shift, 2.0);
  }
  // The turntable axis against the truth (direction up to sign): main's turns
  // are ±2.5°, so the axis is as good as main's frame allows. Measured 0.047°.
  const Eigen::Vector3d d_true = vec(truth["turntable"]["axis_direction"]).normalized();
  const Eigen::Vector3d d =
      Eigen::Vector3d(head.turntable_axis->direction[0], head.turntable_axis->direction[1],
                      head.turntable_axis->direction[2]);
  const double axis_angle = std::acos(std::min(1.0, std::abs(d.dot(d_true)))) / kDeg;
  std::cout << "[ figures  ] turntable axis direction error " << axis_angle << "°, rms "
            << summary["rms_mm"] << " mm\n";
  EXPECT_LT(axis_angle, 0.5);
  EXPECT_LT(summary["rms_mm"].get<double>(), 0.5);
}

TEST_F(RingHead, MergedSurroundCloudPlacesEverySphere) {
  const fs::path merged = work_->path() / "merged.ply";
  const test::ToolResult r =
      test::runTool("reconstruct --json --calib-dir " + (kFixture / "calib").string() + " --head " +
                    headFile().string() + " --out " + merged.string() + " --per-camera " +
                    (work_->path() / "clouds").string() + " " +
                    (kFixture / "surround" / "test" / "surround").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const formats::PointCloud cloud = formats::readPly(merged);
  const std::vector<std::string> names = formats::cameraNamesOf(cloud);
  EXPECT_EQ(names, (std::vector<std::string>{"main", "cam90", "cam180", "cam270"}));
  for (const std::string& camera : names)
    EXPECT_TRUE(fs::exists(work_->path() / "clouds" / ("cloud-" + camera + ".ply"))) << camera;

  const json truth = readJson(kFixture / "surround" / "truth.json");
  int spheres = 0;
  for (const json& o : truth["scenes"]["surround"]["objects"]) {
    if (o["type"] != "sphere") continue;
    ++spheres;
    const std::string name = o["name"];
    SCOPED_TRACE(name);
    const Eigen::Vector3d centre = vec(o["center"]);
    const double radius = o["radius"];
    const algo::Points3d points = near(cloud, centre, radius + 4.0);
    ASSERT_GT(points.size(), 500u);
    const algo::SphereFit fit = algo::fitSphere(points);
    const double centre_error = (fit.sphere.centre - centre).norm();
    std::cout << "[ figures  ] " << name << ": " << points.size() << " points, free radius "
              << fit.sphere.radius << " mm, centre error " << centre_error << " mm, rmse "
              << fit.rmse << " mm\n";
    // The radius is the camera's own calibration (the extrinsics are rigid):
    // board/sim's quick head gives 50 mm spheres within ~0.05 mm (the test
    // scenes of docs/formats.md, simulated dataset).
    EXPECT_NEAR(fit.sphere.radius, radius, 0.05);
    // The centre: the per-direction calibration's absolute placement (~1 mm,
    // see the pose test), carried into the head frame by the extrinsics.
    // Measured 0.62–0.99 mm.
    EXPECT_LT(centre_error, 2.0);

    // cylscan evaluate reads the merged layout (camera property, comments).
    if (name == "sphere_cam90") {
      formats::PointCloud crop;
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        const Eigen::Vector3d x(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
        if ((x - centre).norm() < radius + 4.0) {
          formats::PointCloud one;
          one.xyz = {cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]};
          for (std::size_t p = 0; p < cloud.property_names.size(); ++p) {
            if (cloud.property_names[p] != formats::kCameraProperty) {
              one.property_names.push_back(cloud.property_names[p]);
              one.properties.push_back({cloud.properties[p][i]});
            }
          }
          formats::appendCameraCloud(crop, one, 1, "cam90");
        }
      }
      crop.comments.resize(1);  // one camera line is enough
      const fs::path file = work_->path() / "crop.ply";
      formats::writePly(file, crop);
      const test::ToolResult e =
          test::runTool("evaluate sphere --json --radius 50 " + file.string());
      ASSERT_EQ(e.exit_code, 0) << e.output;
      EXPECT_NE(e.output.find("radius"), std::string::npos) << e.output;
    }
  }
  EXPECT_EQ(spheres, 4);
}

TEST_F(RingHead, CalibrateHeadNamesWhatIsMissing) {
  const std::string calib = " --calib-dir " + (kFixture / "calib").string();
  const std::string out = " --out " + (work_->path() / "bad-head.json").string();
  const fs::path tt = kFixture / "turntable";
  // A bundle without turntable_deg, and no --turn for it.
  const fs::path surround = kFixture / "surround" / "test" / "surround";
  test::ToolResult r = test::runTool("calibrate-head" + calib + out + " " + surround.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("turntable_deg"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("capture.json"), std::string::npos) << r.output;
  // Main at one angle only: the axis is not determined.
  std::string one_turn;
  for (const char* id : {"turn00", "turn01", "turn02", "turn03"})
    one_turn += " " + (tt / id).string();
  r = test::runTool("calibrate-head" + calib + out + one_turn);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("two turntable angles"), std::string::npos) << r.output;
  // A camera that never saw the target.
  r = test::runTool("calibrate-head" + calib + out + " " + (tt / "turn00").string() + " " +
                    (tt / "turn04").string() + " " + (tt / "turn05").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("camera 'cam180'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(work_->path() / "bad-head.json"));
  // --turn overrides capture.json (here with the same angles: the same result).
  std::string bundles, turns;
  for (const auto& entry : fs::directory_iterator(tt)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_directory() || !name.starts_with("turn")) continue;
    bundles += " " + entry.path().string();
    const json capture = readJson(entry.path() / "capture.json");
    turns += " --turn " + entry.path().string() + "=" +
             std::to_string(capture["turntable_deg"].get<double>());
  }
  r = test::runTool("calibrate-head" + calib + out + turns + bundles);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const formats::HeadExtrinsics a = formats::readHeadExtrinsics(headFile());
  const formats::HeadExtrinsics b = formats::readHeadExtrinsics(work_->path() / "bad-head.json");
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(a.pose("cam90").T[i], b.pose("cam90").T[i], 1e-9);
}

// The held-out sphere of turntable/check/: each check bundle is a turn that
// brings it before one camera; its centre found in that camera's cloud, taken
// to the head frame by the extrinsics and back to the world (the head frame
// at turn 0) through the known turn about the fitted axis.
TEST_F(RingHead, TheHeldOutSphereAgreesBetweenNeighbouringCameras) {
  const json truth = readJson(kFixture / "turntable" / "truth.json");
  const formats::HeadExtrinsics head = formats::readHeadExtrinsics(headFile());
  algo::TurntableAxis axis;
  for (int i = 0; i < 3; ++i) {
    axis.point(i) = head.turntable_axis->point[i];
    axis.direction(i) = head.turntable_axis->direction[i];
  }
  const double radius = truth["check"]["radius"];
  const Eigen::Vector3d world_truth = vec(truth["check"]["center"]);
  std::map<std::string, Eigen::Vector3d> world;  // by camera
  double worst_single_rmse = 0;
  for (const auto& [id, turn] : truth["check"]["turns"].items()) {
    const std::string camera = turn["facing"];
    SCOPED_TRACE(id + " " + camera);
    const fs::path bundle = kFixture / "turntable" / "check" / id;
    const fs::path out = work_->path() / ("check-" + id);
    const test::ToolResult r =
        test::runTool("reconstruct --calib-dir " + (kFixture / "calib").string() + " --head " +
                      headFile().string() + " --out " + (out / "merged.ply").string() +
                      " --per-camera " + out.string() + " " + bundle.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const formats::PointCloud own = formats::readPly(out / ("cloud-" + camera + ".ply"));
    // The true centre in the camera's frame, for the single-camera RMSE.
    const algo::RigidPose true_pose = poseOf(truth["head"]["cameras"][camera]);
    const Eigen::Vector3d in_camera =
        true_pose.R.transpose() * (vec(turn["centers_head"][0]) - true_pose.T);
    const algo::Points3d points = near(own, in_camera, radius + 4.0);
    ASSERT_GT(points.size(), 300u);
    const algo::SphereFit fit = algo::fitSphere(points);
    // The single-camera RMSE: the points against the true sphere.
    const std::vector<double> residuals = algo::sphereResiduals(points, {in_camera, radius});
    const double rmse = algo::residualStats(residuals).rmse;
    worst_single_rmse = std::max(worst_single_rmse, rmse);
    const Eigen::Vector3d in_head = poseOf(head.pose(camera)).apply(fit.sphere.centre);
    const Eigen::Vector3d w = axis.turn(-turn["turntable_deg"].get<double>()).apply(in_head);
    std::cout << "[ figures  ] check " << id << " by " << camera << " at " << turn["turntable_deg"]
              << "°: single-camera rmse " << rmse << " mm (about its own fit " << fit.rmse
              << " mm), world centre error " << (w - world_truth).norm() << " mm\n";
    world[camera] = w;
  }
  ASSERT_GE(world.size(), 2u);
  // Every pair (the check turns bring the sphere before main and its two
  // neighbours cam90 and cam270). The brief's criterion: the cameras agree to
  // within the single-camera RMSE against the truth. That RMSE is dominated by
  // the per-direction calibration's absolute placement (~0.4 mm, the same
  // bias main's own sphere shows), which the extrinsics carry over consistently
  // (all three world centres are off the truth by the same ~0.74 mm), so the
  // cameras agree far better than it.
  for (auto a = world.begin(); a != world.end(); ++a) {
    for (auto b = std::next(a); b != world.end(); ++b) {
      const double disagreement = (a->second - b->second).norm();
      std::cout << "[ figures  ] " << a->first << " vs " << b->first << ": centres " << disagreement
                << " mm apart; single-camera rmse <= " << worst_single_rmse << " mm\n";
      EXPECT_LT(disagreement, worst_single_rmse) << a->first << " vs " << b->first;
    }
  }
}

}  // namespace
}  // namespace cylscan
