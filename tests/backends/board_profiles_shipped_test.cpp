// SPDX-License-Identifier: Apache-2.0
// Every board profile the repository ships (board/*/board.toml, installed to
// /usr/share/cylscan/board/<name>/) loads with the firmware's own loader, and
// declares the lines and cameras its README and wiring table promise.
#include <algorithm>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/board_profile.hpp"
#include "drivers/sim/head_config.hpp"
#include "firmware/scan_profile.hpp"
#include "profile_support.hpp"

namespace cylscan::drivers {
namespace {

namespace fs = std::filesystem;
using test::boardDir;

// What a shipped profile must declare. A line is "NAME" (looked up by name)
// or "chip:offset"; a leading '!' marks it active low.
struct Expected {
  std::map<std::string, std::string> lines;  // role → line
  CameraBackendKind backend;
  TriggerMode trigger;
  std::string device;
  bool virtual_head = false;
};

const std::map<std::string, Expected>& shipped() {
  static const std::map<std::string, Expected> boards = {
      {"sim",
       {{{"step", "step"},
         {"dir", "dir"},
         {"enable", "enable"},
         {"light", "light"},
         {"home", "home"},
         {"fault", "fault"},
         {"trigger", "trigger"}},
        CameraBackendKind::Sim,
        TriggerMode::GpioPulse,
        "main",
        true}},
      {"sim360",  // the 360° virtual head: four cameras on one trigger line, a ring plan
       {{{"step", "step"},
         {"dir", "dir"},
         {"enable", "enable"},
         {"light", "light"},
         {"home", "home"},
         {"fault", "fault"},
         {"trigger", "trigger"}},
        CameraBackendKind::Sim,
        TriggerMode::GpioPulse,
        "main",
        true}},
      {"rpi5",
       {{{"step", "GPIO17"},
         {"dir", "GPIO27"},
         {"enable", "!GPIO22"},
         {"trigger", "GPIO23"},
         {"light", "GPIO24"},
         {"home", "!GPIO25"},
         {"fault", "!GPIO26"}},
        CameraBackendKind::V4l2,
        TriggerMode::GpioPulse,
        "/dev/video0"}},
      {"rpi4",
       {{{"step", "GPIO17"},
         {"dir", "GPIO27"},
         {"enable", "!GPIO22"},
         {"trigger", "GPIO23"},
         {"light", "GPIO24"},
         {"home", "!GPIO25"},
         {"fault", "!GPIO26"}},
        CameraBackendKind::Libcamera,
        TriggerMode::GpioPulse,
        "0"}},
      {"generic-arm64",
       {{{"step", "gpiochip0:0"},
         {"dir", "gpiochip0:1"},
         {"enable", "!gpiochip0:2"},
         {"light", "gpiochip0:3"},
         {"trigger", "gpiochip0:4"},
         {"home", "!gpiochip0:5"}},
        CameraBackendKind::V4l2,
        TriggerMode::FreeRunning,
        "/dev/video0"}},
      // The gpio-sim line names of the emulated board (docs/emulated-board.md).
      {"qemu-virt",
       {{{"step", "step"},
         {"dir", "dir"},
         {"enable", "enable"},
         {"trigger", "trigger"},
         {"light", "light"},
         {"home", "home"}},
        CameraBackendKind::V4l2,
        TriggerMode::GpioPulse,
        "/dev/video0"}},
  };
  return boards;
}

std::vector<std::string> profileFolders() {
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(boardDir(""))) {
    if (e.is_directory() && fs::exists(e.path() / "board.toml"))
      names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// The profile's lines as role → "NAME" / "chip:offset", '!' for active low.
std::map<std::string, std::string> declaredLines(const GpioProfile& g) {
  std::map<std::string, std::string> out;
  auto add = [&out](const std::string& role, const LineSpec& s) {
    const std::string where = s.name.empty() ? s.chip + ":" + std::to_string(s.offset) : s.name;
    out[role] = (s.active_low ? "!" : "") + where;
  };
  add("step", g.step);
  add("dir", g.dir);
  add("enable", g.enable);
  add("light", g.light);
  add("home", g.home);
  if (g.fault) add("fault", *g.fault);
  for (const auto& [key, spec] : g.triggers)
    add(key, spec);
  return out;
}

TEST(ShippedBoardProfiles, AreExactlyTheDocumentedBoards) {
  std::vector<std::string> expected;
  for (const auto& [name, e] : shipped())
    expected.push_back(name);
  EXPECT_EQ(profileFolders(), expected)
      << "a board folder was added or removed: list it here with what it declares";
}

TEST(ShippedBoardProfiles, EachLoadsAndDeclaresItsLinesAndCamera) {
  for (const std::string& name : profileFolders()) {
    SCOPED_TRACE("board/" + name);
    const auto it = shipped().find(name);
    ASSERT_NE(it, shipped().end());
    const Expected& want = it->second;

    BoardProfile p;
    ASSERT_NO_THROW(p = loadBoardProfile(boardDir(name)));
    EXPECT_EQ(p.name, name) << "[board] name must be the folder's name (its install path)";
    EXPECT_FALSE(p.description.empty());
    EXPECT_EQ(declaredLines(p.gpio), want.lines);
    EXPECT_EQ(p.sim.has_value(), want.virtual_head);

    ASSERT_FALSE(p.cameras.empty());
    const CameraProfile& main = p.cameras.front();
    EXPECT_EQ(main.name, "main");
    EXPECT_EQ(main.backend, want.backend);
    EXPECT_EQ(main.config.trigger, want.trigger);
    EXPECT_EQ(main.device, want.device);
    for (const CameraProfile& c : p.cameras) {
      if (c.config.trigger == TriggerMode::GpioPulse) {
        EXPECT_EQ(p.gpio.triggers.count(c.trigger_line), 1U) << c.name << ": " << c.trigger_line;
      }
    }
    // A stage the step executor can drive: whole steps per degree well above one.
    EXPECT_GT(p.stage.stepsPerDeg(), 10.0);
    // Its [scan] is one the firmware reads (start angles, a plan it knows).
    const firmware::ScanProfile scan = firmware::readScanProfile(p);
    EXPECT_NE(scan.period_high_deg, scan.period_low_deg);
  }
}

// Each board folder has a README telling how to wire and set up the board
// (the package installs it beside the profile).
TEST(ShippedBoardProfiles, EachHasAReadme) {
  for (const std::string& name : profileFolders()) {
    SCOPED_TRACE("board/" + name);
    EXPECT_TRUE(fs::exists(boardDir(name) / "README.md"));
  }
}

// The emulated board's gpio-sim chip must carry the names the profile looks
// up, and its feeder models it with tests/emulated-board/head.toml (the
// virtual head with this profile's stage and camera): the same step geometry,
// home window and image size; the profile's image latency covers the head
// camera's exposure and readout too (the in-process twin of the emulated
// board's scan runs that head with this profile).
TEST(ShippedBoardProfiles, TheEmulatedBoardMatchesItsFeedersHead) {
  const BoardProfile virt = loadBoardProfile(boardDir("qemu-virt"));
  const sim::HeadConfig head = sim::loadHeadConfig(std::filesystem::path(CYLSCAN_SOURCE_DIR) /
                                                   "tests/emulated-board/head.toml");
  EXPECT_DOUBLE_EQ(virt.stage.stepsPerDeg(), head.stage.full_steps_per_rev * head.stage.microsteps *
                                                 head.stage.gear_ratio / 360.0);
  EXPECT_DOUBLE_EQ(virt.stage.home_offset_deg, head.stage.home_window_deg / 2);
  const std::set<std::string> names{virt.gpio.step.name,   virt.gpio.dir.name,
                                    virt.gpio.enable.name, virt.gpio.light.name,
                                    virt.gpio.home.name,   virt.gpio.triggers.at("trigger").name};
  EXPECT_EQ(names, (std::set<std::string>{"step", "dir", "enable", "trigger", "light", "home"}));
  ASSERT_EQ(head.cameras.size(), 1U);
  const sim::CameraParams& camera = head.cameras.front();
  const CameraProfile& main = virt.camera("main");
  EXPECT_EQ(main.config.width, camera.width);
  EXPECT_EQ(main.config.height, camera.height);
  EXPECT_EQ(main.config.stream, FrameStream::Continuous);
  EXPECT_GT(main.image_latency_ms,
            (camera.trigger_latency_us + camera.exposure_us + camera.readout_us) / 1000.0);
}

}  // namespace
}  // namespace cylscan::drivers
