// SPDX-License-Identifier: Apache-2.0
// A build without the virtual head (CYLSCAN_WITH_SIM=OFF; built only then):
// sim boards are refused by name, hardware boards still load, the daemon
// asks for a board, and `cylscan simulate` and `scan` say why they cannot.
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "drivers/board.hpp"
#include "drivers/board_profile.hpp"
#include "drivers/toml_reader.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "tests/support/run_tool.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan {
namespace {

namespace fs = std::filesystem;
using test_support::TempDir;

fs::path boardDir(const std::string& name) {
  return fs::path(CYLSCAN_SOURCE_DIR) / "board" / name;
}

using test_support::runTool;
using test_support::ToolResult;

constexpr const char* kOff = "CYLSCAN_WITH_SIM=OFF";

TEST(WithoutSim, TheBuildSaysSo) {
  EXPECT_FALSE(drivers::virtualHeadBuilt());
}

TEST(WithoutSim, TheShippedVirtualHeadsAreRefusedAtTheirFirstSimCamera) {
  for (const char* name : {"sim", "sim360"}) {
    try {
      drivers::loadBoardProfile(boardDir(name));
      ADD_FAILURE() << name << " loaded";
    } catch (const drivers::ConfigError& e) {
      EXPECT_EQ(e.file(), (boardDir(name) / "board.toml").string());
      EXPECT_EQ(e.key(), "camera[0].backend");
      EXPECT_NE(std::string(e.what()).find(kOff), std::string::npos) << e.what();
    }
  }
}

TEST(WithoutSim, ASimTableIsRefusedByItsKey) {
  TempDir dir;
  dir.write("board.toml", R"([board]
name = "test"

[gpio]
step = { name = "GPIO17" }
dir = { name = "GPIO27" }
enable = { name = "GPIO22" }
light = { name = "GPIO24" }
home = { name = "GPIO25" }
trigger = { name = "GPIO23" }

[[camera]]
name = "main"
backend = "v4l2"
device = "/dev/video0"

[sim]
head = "head.toml"
)");
  try {
    drivers::loadBoardProfile(dir.path());
    ADD_FAILURE() << "the profile loaded";
  } catch (const drivers::ConfigError& e) {
    EXPECT_EQ(e.key(), "sim");
    EXPECT_NE(std::string(e.what()).find(kOff), std::string::npos) << e.what();
  }
}

TEST(WithoutSim, HardwareBoardsStillLoad) {
  for (const char* name : {"rpi4", "rpi5", "generic-arm64", "qemu-virt"}) {
    const drivers::BoardProfile p = drivers::loadBoardProfile(boardDir(name));
    EXPECT_FALSE(p.sim) << name;
  }
}

TEST(WithoutSim, BoardOpenRefusesAProfileWithAVirtualHead) {
  drivers::BoardProfile p = drivers::loadBoardProfile(boardDir("rpi4"));
  p.sim = drivers::SimProfile{};
  try {
    drivers::Board::open(std::move(p));
    ADD_FAILURE() << "the board opened";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(kOff), std::string::npos) << e.what();
  }
}

TEST(WithoutSim, TheDaemonNeedsABoard) {
  TempDir dir;
  fs::create_directories(dir.path() / "bin");
  const firmware::DaemonDefaults d = firmware::daemonDefaults(dir.path() / "bin");
  EXPECT_TRUE(d.board.empty()) << d.board;
  try {
    firmware::resolveDaemonConfig({}, d, "");
    ADD_FAILURE() << "resolved without a board";
  } catch (const firmware::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--board"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(kOff), std::string::npos) << e.what();
  }
  firmware::DaemonFlags flags;
  flags.board = boardDir("rpi4");
  EXPECT_EQ(firmware::resolveDaemonConfig(flags, d, "").board, boardDir("rpi4"));
}

TEST(WithoutSim, SimulateExitsWithTheReason) {
  TempDir dir;
  const ToolResult r = runTool("simulate --out " + (dir.path() / "data").string() + " --quick");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(kOff), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.path() / "data"));
}

TEST(WithoutSim, ScanNeedsABoardAndHasNoScene) {
  TempDir dir;
  const std::string out = " --out " + (dir.path() / "bundle").string();
  ToolResult r = runTool("scan" + out);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--board"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(kOff), std::string::npos) << r.output;

  r = runTool("scan --board " + boardDir("rpi4").string() + " --scene scene.toml" + out);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--scene"), std::string::npos) << r.output;

  r = runTool("scan --board " + boardDir("sim").string() + out);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(kOff), std::string::npos) << r.output;
}

}  // namespace
}  // namespace cylscan
