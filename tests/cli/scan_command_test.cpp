// SPDX-License-Identifier: Apache-2.0
// `cylscan scan` as a user runs it: one acquisition on a board profile writes
// a capture bundle whose phase is the streamed one; bad requests exit 2.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "formats/capture_bundle.hpp"
#include "tests/cli/cli_support.hpp"
#include "tests/support/small_board.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;

const char* kWall = R"(name = "wall"
[[object]]
type = "plane"
point = [0.0, 0.0, 580.0]
normal = [0.0, 0.0, -1.0]
)";

TEST(ScanCommand, WritesABundleWithTheExecutedAngles) {
  TempDir dir;
  const fs::path board = test_support::smallBoard(dir, kWall);
  const auto run = runTool("scan --json --board " + board.string() + " --frames 9 --out " +
                           (dir.path() / "b").string() + " --camera main --camera aux");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto summary = nlohmann::json::parse(run.output.substr(run.output.find('{')));
  EXPECT_EQ(summary.at("frames").get<int>(), 18);
  const formats::CaptureBundleReader bundle(dir.path() / "b");
  EXPECT_EQ(bundle.info().cameras, (std::vector<std::string>{"main", "aux"}));
  ASSERT_EQ(bundle.frameCount(FringeSet::High), 9);
  EXPECT_EQ(bundle.info().high.stage_deg,
            summary.at("stage_deg").at("high").get<std::vector<double>>());
  EXPECT_EQ(bundle.frameSize("aux"), cv::Size(160, 128));
  // The phase of the saved bundle, offline.
  const auto phase = runTool("phase --json --out " + (dir.path() / "p").string() + " " +
                             (dir.path() / "b").string());
  EXPECT_EQ(phase.exit_code, 0) << phase.output;
  EXPECT_TRUE(fs::exists(dir.path() / "p" / "absolute.tiff"));
}

TEST(ScanCommand, BadRequestsNameWhatIsWrong) {
  TempDir dir;
  const fs::path board = test_support::smallBoard(dir, kWall);
  auto run = runTool("scan --board " + (dir.path() / "nowhere").string() + " --out x");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("nowhere"), std::string::npos) << run.output;
  run = runTool("scan --board " + board.string() + " --cloud c.ply");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("--calib"), std::string::npos) << run.output;
  run = runTool("scan --board " + board.string() + " --out x --camera main --camera side");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("side"), std::string::npos) << run.output;
  dir.write("bad.qcal", "not a calibration");
  run = runTool("scan --board " + board.string() + " --calib " +
                (dir.path() / "bad.qcal").string() + " --cloud c.ply");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("bad.qcal"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace cylscan::test
