// SPDX-License-Identifier: Apache-2.0
// The virtual head's calibration targets: checkerboard poses (stills under
// ambient light) and plane poses (fringe scans), made by one deterministic
// generator and shipped as scene files in a board's scenes/calibration/
// (boardNN.toml, planeNN.toml, NN from 00). `cylscan simulate` renders those
// files and cylscand's calibration session takes them by name, so both see
// the same targets; `cylscan simulate --write-calibration-scenes` writes them
// from the generator. Coordinates: main camera frame, mm.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/geometry.hpp"
#include "drivers/sim/scene.hpp"

namespace cylscan::sim {

// A checkerboard pose as its scene file gives it: the board's centre and its
// rotation vector in degrees (rotationFromVectorDeg), so that the file holds
// the generator's numbers themselves.
struct BoardPose {
  Vec3 center;
  std::array<double, 3> rotation_deg{};
  Checkerboard board() const;  // the default board (9 × 6 inner corners, 12 mm) in this pose
};

// An unbounded plane through `point` with the unit `normal` facing the cameras.
struct PlanePose {
  Vec3 point;
  Vec3 normal;
};

inline constexpr double kBoardAmbient = 0.7;   // room light, projector off
inline constexpr double kPlaneAmbient = 0.03;  // the scenes' default
inline constexpr double kPlaneAlbedo = 0.8;
// The board sequence: kSpreadBoards spread poses, then tilted ones, which
// may face away from a camera by up to kTiltedMaxViewDeg (OpenCV still finds
// every corner at 320 × 256; steeper ones start to fail there).
inline constexpr int kSpreadBoards = 64;
inline constexpr double kTiltedMaxViewDeg = 60.0;

// The first `count` of a fixed sequence of board poses. The first
// kSpreadBoards are spread poses (depths 530–640 mm, tilts up to 22° about x
// and 25° about y, up to 10° in plane) kept when the board faces both cameras
// within 50° and every inner corner lies more than 4 % of main's width
// inside both images. The tilted poses after them constrain the cameras'
// focal lengths (calibration_targets.cpp): each is tilted by 40–55° from the
// bisector of its directions to the two cameras, about an axis that turns by
// 135° from one pose to the next, at depths of 520–640 mm, and kept when it
// faces both cameras within kTiltedMaxViewDeg and its whole checkered area
// lies more than 2 % of the width inside both images. The sequence
// depends on the cameras through these tests and the cameras' centres, not
// on their resolution. std::runtime_error when fewer than `count` fit.
std::vector<BoardPose> calibrationBoardPoses(const CameraModel& main, const CameraModel& aux,
                                             int count);
// `count` planes through (0, 0, z), z evenly over 540–620 mm (580 for one),
// tilted by up to ±10° about x, then ±12° about y. The depths depend on
// `count`: the set of 14 does not begin the set of 20.
std::vector<PlanePose> calibrationPlanePoses(int count);

// "board07": KIND and the index in two digits, as frames and poses are numbered.
std::string calibrationSceneStem(std::string_view kind, int index);
// A board's folder of calibration targets: <board>/scenes/calibration.
std::filesystem::path calibrationScenesDir(const std::filesystem::path& board_dir);

// The scene of a target (name: its stem), as its file loads.
Scene calibrationScene(const BoardPose& pose, int index);
Scene calibrationScene(const PlanePose& pose, int index);
// Its scene file: a header comment, then every number in the fewest digits
// that read back to the same double.
std::string calibrationSceneToml(const BoardPose& pose, int index);
std::string calibrationSceneToml(const PlanePose& pose, int index);

// The targets of one kind ("board" or "plane") in `dir`: KIND00.toml,
// KIND01.toml, … loaded in order; none when `dir` has no KIND00.toml.
// std::invalid_argument naming the folder when the numbers have a gap.
std::vector<Scene> loadCalibrationScenes(const std::filesystem::path& dir, std::string_view kind);

}  // namespace cylscan::sim
