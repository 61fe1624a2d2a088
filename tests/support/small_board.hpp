// SPDX-License-Identifier: Apache-2.0
// A small virtual head as a board profile folder, for tests of what runs on
// boards (the acquisition loop, `cylscan scan`).
#pragma once

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/support/temp_dir.hpp"

namespace cylscan::test_support {

// board/sim at 160×128 (same fields of view), with an ideal projector (no
// eccentricity, so the analytic phase is exact), the given scene and any
// extra lines replacing keys of board.toml.
// A wall a little tilted to the camera: the scene of the small board's scans.
inline constexpr const char* kWallScene = R"(name = "wall"
ambient = 0.03
[[object]]
type = "plane"
point = [0.0, 0.0, 590.0]
normal = [0.1, -0.05, -1.0]
)";

inline std::filesystem::path smallBoard(
    const TempDir& dir, const std::string& scene_toml,
    const std::vector<std::pair<std::string, std::string>>& replace = {}) {
  std::ifstream in(std::filesystem::path(CYLSCAN_SOURCE_DIR) / "board/sim/board.toml");
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  s = std::regex_replace(s, std::regex("width = 1000"), "width = 160");
  s = std::regex_replace(s, std::regex("height = 800"), "height = 128");
  for (const auto& [from, to] : replace)
    s = std::regex_replace(s, std::regex(from), to);
  // The [sim] section: the head inline (every key defaults to head.toml's values).
  s = s.substr(0, s.rfind("\n[sim]") + 1);
  s += "[sim]\nscene = \"scene.toml\"\nseed = 3\nresolution = [160, 128]\n"
       "[sim.head.projector]\neccentricity_mm = 0.0\nsource_offset_mm = [0.0, 0.0, 0.0]\n";
  dir.write("board.toml", s);
  dir.write("scene.toml", scene_toml);
  return dir.path();
}

}  // namespace cylscan::test_support
