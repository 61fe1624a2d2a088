// SPDX-License-Identifier: Apache-2.0
// What `cylscan simulate` was asked for (tools/simulate.cpp parses it).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cylscan::tools {

struct SimulateRequest {
  std::string out;
  // The board whose virtual head renders the dataset (default: the shipped
  // board/sim); --head replaces its head model.
  std::string board;
  std::string head;
  int width = 0;
  int height = 0;
  int frames = 25;
  bool frames_given = false;  // --frames overrides the profile's frames per set
  double noise = 1.0;
  std::uint64_t seed = 1;
  std::vector<std::string> scenes;
  int poses = 14;
  int boards = 14;
  int bit_depth = 0;
  // Scenes of `cylscan study` (rendered with main and aux; none by default).
  int sphere_poses = 0;
  int plane_poses = 0;
  int repeats = 0;
  bool quick = false;
  bool json = false;
  // Write the calibration targets' scene files (--boards boards, --poses
  // planes, generated for the board's head) to `out` instead of rendering.
  bool write_calibration_scenes = false;
  // A 360° head (a ring board such as board/sim360): --camera NAME (the
  // calibration dataset of direction NAME), --turntable (the extrinsics
  // dataset), or neither (a ring scan of the board's default scene).
  std::string camera;
  bool turntable = false;
};

}  // namespace cylscan::tools
