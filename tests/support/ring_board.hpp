// SPDX-License-Identifier: Apache-2.0
// A small 360° virtual head as a board profile folder, for tests of ring
// scans (the acquisition loop, `cylscan scan`): board/sim360 (four cameras,
// main turned by 0/90/180/270° about the projector axis) at 160×128.
#pragma once

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/support/temp_dir.hpp"

namespace cylscan::test_support {

inline std::string readTextFile(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// In front of each camera a wall 590 mm along its view, tilted as the single
// camera tests' wall is: camA's frame is main's turned by A about the
// projector axis (vertical through (120, 0, 0)): X = R_y(A)·p + C_A with
// C_A = (120 − 120 cos A, 0, 120 sin A) (board/sim360/head.toml). The walls
// stay out of each other's views and light (each is > 500 mm from the others'
// rays).
inline std::string fourWalls() {
  std::ostringstream s;
  s << "name = \"four walls\"\nambient = 0.03\n";
  for (const double a_deg : {0.0, 90.0, 180.0, 270.0}) {
    const double a = a_deg * std::numbers::pi / 180.0, c = std::cos(a), sn = std::sin(a);
    auto turn = [&](double x, double y, double z) {
      return std::array<double, 3>{x * c + z * sn, y, -x * sn + z * c};
    };
    const auto p = turn(0.0, 0.0, 590.0);
    const auto n = turn(0.1, -0.05, -1.0);
    s << "[[object]]\ntype = \"plane\"\npoint = [" << p[0] + 120.0 - 120.0 * c << ", " << p[1]
      << ", " << p[2] + 120.0 * sn << "]\nnormal = [" << n[0] << ", " << n[1] << ", " << n[2]
      << "]\n";
  }
  return s.str();
}

// board/sim360 at 160×128 (same fields of view) with an ideal projector (no
// eccentricity or source offset: the shifts are then exactly the stage's, so
// the analytic phase is exact), the scene (default: the four walls), and
// `replace` applied to board.toml.
inline std::filesystem::path ringBoard(
    const TempDir& dir, const std::vector<std::pair<std::string, std::string>>& replace = {},
    const std::string& scene_toml = fourWalls()) {
  const std::filesystem::path source = std::filesystem::path(CYLSCAN_SOURCE_DIR) / "board/sim360";
  std::string board = readTextFile(source / "board.toml");
  board = std::regex_replace(board, std::regex("width = 1000"), "width = 160");
  board = std::regex_replace(board, std::regex("height = 800"), "height = 128");
  for (const auto& [from, to] : replace)
    board = std::regex_replace(board, std::regex(from), to);
  board = board.substr(0, board.rfind("\n[sim]") + 1);
  board +=
      "[sim]\nhead = \"head.toml\"\nscene = \"scene.toml\"\nseed = 3\n"
      "resolution = [160, 128]\n";
  std::string head = readTextFile(source / "head.toml");
  head =
      std::regex_replace(head, std::regex("eccentricity_mm = [-0-9.e]+"), "eccentricity_mm = 0.0");
  head = std::regex_replace(head, std::regex("source_offset_mm = \\[[^\\]]*\\]"),
                            "source_offset_mm = [0.0, 0.0, 0.0]");
  dir.write("board.toml", board);
  dir.write("head.toml", head);
  dir.write("scene.toml", scene_toml);
  return dir.path();
}

}  // namespace cylscan::test_support
