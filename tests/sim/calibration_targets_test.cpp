// SPDX-License-Identifier: Apache-2.0
// The calibration targets: board/sim/scenes/calibration/ holds exactly what
// the generator gives for board/sim's head (so `cylscan simulate` and
// cylscand's calibration session, which read the files, see the generator's
// poses), and a target's scene file reads back to the same doubles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <variant>

#include "drivers/board_profile.hpp"
#include "drivers/sim/calibration_targets.hpp"
#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/head_config.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::sim {
namespace {

namespace fs = std::filesystem;
using test_support::TempDir;

const fs::path kBoard = fs::path(CYLSCAN_SOURCE_DIR) / "board" / "sim";
// What board/sim ships: the paper's 64 checkerboards (every count the
// project's tests and tools ask for fits), 32 tilted ones for the focal
// lengths after them, and simulate's default 14 planes.
constexpr int kShippedBoards = kSpreadBoards + 32;
constexpr int kShippedPlanes = 14;

std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

const CameraParams& camera(const HeadConfig& head, const std::string& name) {
  for (const CameraParams& c : head.cameras)
    if (c.name == name) return c;
  throw std::invalid_argument("no camera " + name);
}

std::vector<BoardPose> boardPoses(const HeadConfig& head, int count) {
  return calibrationBoardPoses(CameraModel(camera(head, "main")), CameraModel(camera(head, "aux")),
                               count);
}

// Bit for bit: the loaded scene is the generated one.
void expectSameScene(const Scene& loaded, const Scene& made) {
  EXPECT_EQ(loaded.name, made.name);
  EXPECT_EQ(loaded.ambient, made.ambient) << made.name;
  ASSERT_EQ(loaded.objects.size(), 1U) << made.name;
  const SceneObject& a = loaded.objects.front();
  const SceneObject& b = made.objects.front();
  EXPECT_EQ(a.name, b.name) << made.name;
  EXPECT_EQ(a.albedo, b.albedo) << made.name;
  ASSERT_EQ(a.shape.index(), b.shape.index()) << made.name;
  if (const auto* p = std::get_if<Plane>(&b.shape)) {
    const auto& q = std::get<Plane>(a.shape);
    EXPECT_EQ(q.point, p->point) << made.name;
    EXPECT_EQ(q.normal, p->normal) << made.name;
    EXPECT_EQ(q.extent, p->extent) << made.name;
  } else {
    const auto& c = std::get<Checkerboard>(b.shape);
    const auto& d = std::get<Checkerboard>(a.shape);
    EXPECT_EQ(d.cols, c.cols) << made.name;
    EXPECT_EQ(d.rows, c.rows) << made.name;
    EXPECT_EQ(d.square_mm, c.square_mm) << made.name;
    EXPECT_EQ(d.center, c.center) << made.name;
    EXPECT_EQ(d.rotation, c.rotation) << made.name;
    EXPECT_EQ(d.albedo_dark, c.albedo_dark) << made.name;
    EXPECT_EQ(d.albedo_light, c.albedo_light) << made.name;
    EXPECT_EQ(d.margin_squares, c.margin_squares) << made.name;
  }
}

// The files are `cylscan simulate --write-calibration-scenes --boards 96
// --poses 14 --out board/sim/scenes/calibration` (board/sim/README.md).
TEST(CalibrationTargets, BoardSimShipsTheGeneratorsPosesForItsHead) {
  const drivers::BoardProfile profile = drivers::loadBoardProfile(kBoard);
  ASSERT_TRUE(profile.sim);
  const fs::path dir = calibrationScenesDir(kBoard);
  const std::vector<Scene> boards = loadCalibrationScenes(dir, "board");
  const std::vector<Scene> planes = loadCalibrationScenes(dir, "plane");
  ASSERT_EQ(boards.size(), static_cast<std::size_t>(kShippedBoards));
  ASSERT_EQ(planes.size(), static_cast<std::size_t>(kShippedPlanes));

  const auto board_poses = boardPoses(profile.sim->head, kShippedBoards);
  for (int i = 0; i < kShippedBoards; ++i) {
    const BoardPose& pose = board_poses[static_cast<std::size_t>(i)];
    const std::string stem = calibrationSceneStem("board", i);
    EXPECT_EQ(readText(dir / (stem + ".toml")), calibrationSceneToml(pose, i)) << stem;
    expectSameScene(boards[static_cast<std::size_t>(i)], calibrationScene(pose, i));
  }
  const auto plane_poses = calibrationPlanePoses(kShippedPlanes);
  for (int i = 0; i < kShippedPlanes; ++i) {
    const PlanePose& pose = plane_poses[static_cast<std::size_t>(i)];
    const std::string stem = calibrationSceneStem("plane", i);
    EXPECT_EQ(readText(dir / (stem + ".toml")), calibrationSceneToml(pose, i)) << stem;
    expectSameScene(planes[static_cast<std::size_t>(i)], calibrationScene(pose, i));
  }
  // Nothing else in the folder: every file there is a target.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir))
    ++files;
  EXPECT_EQ(files, kShippedBoards + kShippedPlanes);
}

// The sequence does not depend on the resolution (the quick head of the tests,
// 320 × 256, gets the same boards) and its first poses do not depend on the
// count: simulate continues the shipped boards with the generator's next ones.
TEST(CalibrationTargets, BoardSequenceIsTheSameAtAnyResolutionAndCount) {
  const drivers::BoardProfile profile = drivers::loadBoardProfile(kBoard);
  const auto full = boardPoses(profile.sim->head, 99);
  const auto quick = boardPoses(withResolution(profile.sim->head, 320, 256), 99);
  const auto few = boardPoses(profile.sim->head, 14);
  ASSERT_EQ(full.size(), 99U);
  ASSERT_EQ(quick.size(), 99U);
  for (std::size_t i = 0; i < full.size(); ++i) {
    EXPECT_EQ(quick[i].center, full[i].center) << i;
    EXPECT_EQ(quick[i].rotation_deg, full[i].rotation_deg) << i;
    if (i < few.size()) {
      EXPECT_EQ(few[i].center, full[i].center) << i;
    }
  }
  EXPECT_THROW(boardPoses(profile.sim->head, 400), std::runtime_error);
}

// The poses after the spread ones are steep to at least one camera, tilted
// both ways about x and y, at several depths, and whole in both images.
TEST(CalibrationTargets, TiltedBoardsFollowTheSpreadOnes) {
  const drivers::BoardProfile profile = drivers::loadBoardProfile(kBoard);
  const HeadConfig& head = profile.sim->head;
  const CameraModel main(camera(head, "main")), aux(camera(head, "aux"));
  const auto poses = boardPoses(head, kShippedBoards);
  double steepest[2] = {0, 0}, min_z = 1e9, max_z = 0;
  int signs[4] = {0, 0, 0, 0};  // normal leaning to −x, +x, −y, +y (tilt about y and x)
  for (int i = kSpreadBoards; i < kShippedBoards; ++i) {
    const Checkerboard b = poses[static_cast<std::size_t>(i)].board();
    double steeper = 0;
    for (int c = 0; c < 2; ++c) {
      const CameraModel& cam = c == 0 ? main : aux;
      const double view =
          std::acos(std::abs((cam.centre() - b.center).normalized().dot(b.rotation.col(2)))) / kDeg;
      EXPECT_LT(view, kTiltedMaxViewDeg) << i;
      steeper = std::max(steeper, view);
      steepest[c] = std::max(steepest[c], view);
      for (const Vec3& corner : b.corners()) {
        const auto px = cam.project(corner);
        ASSERT_TRUE(px) << i;
        EXPECT_GT(px->x(), 0) << i;
        EXPECT_GT(px->y(), 0) << i;
        EXPECT_LT(px->x(), cam.width() - 1) << i;
        EXPECT_LT(px->y(), cam.height() - 1) << i;
      }
    }
    EXPECT_GT(steeper, 40) << i;
    const Vec3 n = b.rotation.col(2);  // away from the cameras
    ++signs[n.x() < 0 ? 0 : 1];
    ++signs[n.y() < 0 ? 2 : 3];
    min_z = std::min(min_z, b.center.z());
    max_z = std::max(max_z, b.center.z());
  }
  EXPECT_GT(steepest[0], 55);
  EXPECT_GT(steepest[1], 55);
  for (int s : signs)
    EXPECT_GE(s, 8);
  EXPECT_LT(min_z, 540);
  EXPECT_GT(max_z, 620);
}

// Planes: through (0, 0, z), z evenly over 540–620 mm, facing the cameras
// (normal towards −z) within the documented tilts.
TEST(CalibrationTargets, PlanesSpanTheWorkingRange) {
  const auto planes = calibrationPlanePoses(kShippedPlanes);
  ASSERT_EQ(planes.size(), static_cast<std::size_t>(kShippedPlanes));
  EXPECT_EQ(planes.front().point, Vec3(0, 0, 540));
  EXPECT_EQ(planes.back().point, Vec3(0, 0, 620));
  for (const PlanePose& p : planes) {
    EXPECT_NEAR(p.normal.norm(), 1.0, 1e-15);
    EXPECT_LT(p.normal.z(), -std::cos(16 * kDeg));  // ±10° and ±12° together
  }
  EXPECT_EQ(calibrationPlanePoses(1).front().point, Vec3(0, 0, 580));
}

// Every number reads back to the same double, whatever its size or sign. (The
// normals are the generator's: the reader normalises a normal, which can move
// the last bit of a vector that is not the rounded unit vector of itself.)
TEST(CalibrationTargets, SceneFilesReadBackExactly) {
  TempDir tmp;
  const double awkward[] = {0.1,     -0.0,          1e-300, 123456789.123456789,
                            -2.5e17, 6.02214076e23, 600,    1.0 / 3.0};
  const auto normals = calibrationPlanePoses(8);
  for (int i = 0; i < 8; ++i) {
    BoardPose b;
    b.center = Vec3(awkward[i], awkward[(i + 3) % 8], 580 + awkward[(i + 5) % 8]);
    b.rotation_deg = {awkward[(i + 1) % 8], 1.0 / (i + 7), -awkward[(i + 2) % 8]};
    const fs::path board_file = tmp.path() / (calibrationSceneStem("board", i) + ".toml");
    std::ofstream(board_file) << calibrationSceneToml(b, i);
    expectSameScene(loadScene(board_file), calibrationScene(b, i));

    PlanePose p{Vec3(awkward[i], 1.0 / (i + 3), 600 + i / 7.0),
                normals[static_cast<std::size_t>(i)].normal};
    const fs::path plane_file = tmp.path() / (calibrationSceneStem("plane", i) + ".toml");
    std::ofstream(plane_file) << calibrationSceneToml(p, i);
    expectSameScene(loadScene(plane_file), calibrationScene(p, i));
  }
  EXPECT_EQ(loadCalibrationScenes(tmp.path(), "board").size(), 8U);
  EXPECT_EQ(loadCalibrationScenes(tmp.path(), "plane").size(), 8U);
}

TEST(CalibrationTargets, FolderIsNumberedFromZeroWithoutGaps) {
  TempDir tmp;
  EXPECT_TRUE(loadCalibrationScenes(tmp.path() / "absent", "board").empty());
  const auto planes = calibrationPlanePoses(3);
  for (int i : {0, 1, 2}) {
    std::ofstream(tmp.path() / (calibrationSceneStem("plane", i) + ".toml"))
        << calibrationSceneToml(planes[static_cast<std::size_t>(i)], i);
  }
  std::ofstream(tmp.path() / "README.md") << "not a target\n";
  std::ofstream(tmp.path() / "plane3.toml") << "not a target's name\n";
  EXPECT_EQ(loadCalibrationScenes(tmp.path(), "plane").size(), 3U);
  EXPECT_TRUE(loadCalibrationScenes(tmp.path(), "board").empty());

  fs::remove(tmp.path() / "plane01.toml");
  try {
    loadCalibrationScenes(tmp.path(), "plane");
    ADD_FAILURE() << "a gap was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(tmp.path().string()), std::string::npos) << what;
    EXPECT_NE(what.find("plane01.toml is missing"), std::string::npos) << what;
  }
  EXPECT_EQ(calibrationSceneStem("board", 7), "board07");
  EXPECT_EQ(calibrationSceneStem("plane", 13), "plane13");
  EXPECT_THROW(calibrationSceneStem("board", 100), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::sim
