// SPDX-License-Identifier: Apache-2.0
// `cylscan scan` on a 360° ring profile (board/sim360, small): every camera
// of the profile is scanned, the ring layout is reported, and `cylscan phase
// --camera NAME` gives each camera's maps from its own sets.
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "formats/capture_bundle.hpp"
#include "tests/cli/cli_support.hpp"
#include "tests/support/ring_board.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;

nlohmann::json jsonOf(const std::string& output) {
  return nlohmann::json::parse(output.substr(output.find('{')));
}

TEST(RingScanCommand, ScansEveryCameraAndEachCamerasPhaseComesFromItsOwnSets) {
  TempDir dir;
  const fs::path board = test_support::ringBoard(dir);
  const fs::path bundle = dir.path() / "b";
  const auto run =
      runTool("scan --json --board " + board.string() + " --frames 9 --out " + bundle.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto summary = jsonOf(run.output);
  const std::vector<std::string> cameras{"main", "cam90", "cam180", "cam270"};
  EXPECT_EQ(summary.at("cameras").get<std::vector<std::string>>(), cameras);
  EXPECT_EQ(summary.at("plan"), "ring");
  const auto& ring = summary.at("ring");
  EXPECT_EQ(ring.at("frames"), 9);
  EXPECT_GT(ring.at("step_steps").get<int>(), 0);
  for (const char* key : {"start_deg", "sweep2_start_deg", "step_deg"})
    EXPECT_TRUE(ring.at(key).is_number()) << key;
  EXPECT_GE(ring.at("noise_gain").at("high").get<double>(), 1.0);
  EXPECT_EQ(ring.at("cameras").size(), 4u);
  for (const auto& camera : cameras) {
    EXPECT_GT(ring.at("margins_deg").at(camera).at("window").get<double>(), 1.0) << camera;
    EXPECT_GT(ring.at("margins_deg").at(camera).at("half").get<double>(), 1.0) << camera;
  }

  const formats::CaptureBundleReader reader(bundle);
  EXPECT_EQ(reader.info().cameras, cameras);
  EXPECT_EQ(reader.info().high.stage_deg,
            summary.at("stage_deg").at("high").get<std::vector<double>>());
  for (const auto& camera : cameras) {
    SCOPED_TRACE(camera);
    const bool swapped = ring.at("cameras").at(camera) == "low";
    EXPECT_EQ(reader.info().hasOwnSets(camera), swapped);
    // A swapped camera's high set is sweep 2, main's low set.
    EXPECT_EQ(reader.info().setOf(camera, FringeSet::High).stage_deg,
              summary.at("stage_deg").at(swapped ? "low" : "high").get<std::vector<double>>());
    const fs::path out = dir.path() / ("p-" + camera);
    const auto phase = runTool("phase --json --camera " + camera + " --out " + out.string() + " " +
                               bundle.string());
    ASSERT_EQ(phase.exit_code, 0) << phase.output;
    const auto maps = jsonOf(phase.output);
    EXPECT_EQ(maps.at("own_sets"), swapped);
    EXPECT_EQ(maps.at("frames").at("low"), 9);
    // Each camera sees its wall over the whole view.
    EXPECT_GT(maps.at("valid_fraction").get<double>(), 0.9);
    EXPECT_TRUE(fs::exists(out / "absolute.tiff"));
  }
}

TEST(RingScanCommand, PrintsTheRingLayoutAndScansTheCamerasAsked) {
  TempDir dir;
  const fs::path board = test_support::ringBoard(dir);
  const fs::path bundle = dir.path() / "b";
  const auto run = runTool("scan --board " + board.string() +
                           " --frames 6 --camera main --camera cam90 --out " + bundle.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("ring plan: 6 frames a sweep"), std::string::npos) << run.output;
  // The layout is the head's (planned for all four cameras: the per-camera
  // calibrations hold for it), whichever cameras are scanned.
  for (const char* camera : {"main: sweep 1 = ", "cam90: sweep 1 = ", "cam180: sweep 1 = "})
    EXPECT_NE(run.output.find(camera), std::string::npos) << run.output;
  const formats::CaptureBundleReader reader(bundle);
  EXPECT_EQ(reader.info().cameras, (std::vector<std::string>{"main", "cam90"}));
  EXPECT_EQ(reader.info().extra.at("ring").at("cameras").size(), 4u);
  // A camera the profile has but the scan did not take.
  const auto phase =
      runTool("phase --camera cam180 --out " + (dir.path() / "p").string() + " " + bundle.string());
  EXPECT_EQ(phase.exit_code, 2) << phase.output;
  EXPECT_NE(phase.output.find("cam180"), std::string::npos) << phase.output;
}

}  // namespace
}  // namespace cylscan::test
