// SPDX-License-Identifier: Apache-2.0
// `cylscan simulate` and the calibration targets of a board's
// scenes/calibration/: --write-calibration-scenes gives board/sim's files
// byte for byte, and a dataset renders the board's files (the first N),
// continuing the boards with the generator and generating all the planes when
// asked for more than the board has.
#include <algorithm>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kBoard = fs::path(CYLSCAN_SOURCE_DIR) / "board" / "sim";
const fs::path kTargets = kBoard / "scenes" / "calibration";

std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::string> fileNames(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// A key's array value in a target file ("center = [x, y, z]"), as JSON: the
// file writes the shortest digits that read back, so do truth.json's.
json arrayIn(const fs::path& file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key + " = ", 0) == 0) return json::parse(line.substr(key.size() + 3));
  }
  ADD_FAILURE() << file << " has no " << key;
  return json::array();
}

// board/sim with only the targets `keep` of its own, plus `extra` files.
fs::path boardWithTargets(const TempDir& dir, const std::vector<std::string>& keep,
                          const std::vector<std::pair<std::string, std::string>>& extra) {
  fs::path board = dir.path() / "board";
  fs::create_directories(board / "scenes" / "calibration");
  fs::copy_file(kBoard / "board.toml", board / "board.toml");
  fs::copy_file(kBoard / "head.toml", board / "head.toml");
  for (const auto& e : fs::directory_iterator(kBoard / "scenes")) {
    if (e.is_regular_file()) fs::copy_file(e.path(), board / "scenes" / e.path().filename());
  }
  for (const std::string& name : keep)
    fs::copy_file(kTargets / name, board / "scenes" / "calibration" / name);
  for (const auto& [name, text] : extra)
    std::ofstream(board / "scenes" / "calibration" / name) << text;
  return board;
}

json simulate(const fs::path& board, const fs::path& out, const std::string& counts) {
  const ToolResult run = runTool("simulate --quick --frames 3 --json --board " + board.string() +
                                 " " + counts + " --out " + out.string());
  EXPECT_EQ(run.exit_code, 0) << run.output;
  return json::parse(readText(out / "truth.json"), nullptr, false);
}

TEST(SimulateTargets, WriteCalibrationScenesGivesBoardSimsFiles) {
  TempDir dir;
  const fs::path out = dir.path() / "targets";
  const ToolResult run = runTool(
      "simulate --write-calibration-scenes --json --boards 96 --poses 14 "
      "--out " +
      out.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const json summary = json::parse(run.output);
  EXPECT_EQ(summary.at("boards"), 96);
  EXPECT_EQ(summary.at("planes"), 14);
  const std::vector<std::string> names = fileNames(out);
  EXPECT_EQ(names, fileNames(kTargets));
  for (const std::string& name : names)
    EXPECT_EQ(readText(out / name), readText(kTargets / name)) << name;
}

// The boards: the board's files in order (board01 edited here), then the
// generator's next poses (board02 is board/sim's, which is the generator's).
// The planes: the first two of the board's files (plane00 edited here).
TEST(SimulateTargets, RendersTheBoardsFilesThenTheGenerators) {
  TempDir dir;
  const std::string moved_board =
      "name = \"board01\"\nambient = 0.7\n[[object]]\ntype = \"checkerboard\"\n"
      "center = [3.5, -2.0, 575.0]\nrotation_deg = [10.0, -15.0, 0.0]\n";
  const std::string moved_plane =
      "name = \"plane00\"\n[[object]]\ntype = \"plane\"\nname = \"plane\"\n"
      "point = [0.0, 0.0, 600.0]\nnormal = [0.0, 0.0, -1.0]\n";
  const fs::path board =
      boardWithTargets(dir, {"board00.toml", "plane01.toml"},
                       {{"board01.toml", moved_board}, {"plane00.toml", moved_plane}});
  const json truth = simulate(board, dir.path() / "data", "--boards 3 --poses 2");
  ASSERT_TRUE(truth.is_object());

  EXPECT_EQ(truth.at("board").size(), 3U);
  EXPECT_EQ(truth.at("board").at("00").at("center"), arrayIn(kTargets / "board00.toml", "center"));
  EXPECT_EQ(truth.at("board").at("01").at("center"), json::parse("[3.5, -2.0, 575.0]"));
  EXPECT_EQ(truth.at("board").at("02").at("center"), arrayIn(kTargets / "board02.toml", "center"));

  ASSERT_EQ(truth.at("calib").size(), 2U);
  EXPECT_EQ(truth.at("calib").at("pose00").at("point"), json::parse("[0.0, 0.0, 600.0]"));
  EXPECT_EQ(truth.at("calib").at("pose00").at("normal"), json::parse("[0.0, 0.0, -1.0]"));
  EXPECT_EQ(truth.at("calib").at("pose01").at("point"),
            arrayIn(kTargets / "plane01.toml", "point"));
  EXPECT_EQ(truth.at("calib").at("pose01").at("normal"),
            arrayIn(kTargets / "plane01.toml", "normal"));
  const json capture =
      json::parse(readText(dir.path() / "data" / "calib" / "pose00" / "capture.json"));
  EXPECT_EQ(capture.at("scene"), "pose00");
}

// More planes than the board has: all generated, spread over 540–620 mm.
TEST(SimulateTargets, MorePlanesThanTheBoardHasAreAllGenerated) {
  TempDir dir;
  const fs::path board =
      boardWithTargets(dir, {"board00.toml", "plane00.toml", "plane01.toml"}, {});
  const json truth = simulate(board, dir.path() / "data", "--boards 1 --poses 3");
  ASSERT_TRUE(truth.is_object());
  ASSERT_EQ(truth.at("calib").size(), 3U);
  EXPECT_EQ(truth.at("calib").at("pose00").at("point"), json::parse("[0.0, 0.0, 540.0]"));
  EXPECT_EQ(truth.at("calib").at("pose01").at("point"), json::parse("[0.0, 0.0, 580.0]"));
  EXPECT_EQ(truth.at("calib").at("pose02").at("point"), json::parse("[0.0, 0.0, 620.0]"));
}

}  // namespace
}  // namespace cylscan::test
