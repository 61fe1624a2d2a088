// SPDX-License-Identifier: Apache-2.0
#include "drivers/board_profile.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "drivers/sim/geometry.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/scan_profile.hpp"
#include "profile_support.hpp"

namespace cylscan::drivers {
namespace {

using firmware::PlanKind;
using firmware::readScanProfile;
using firmware::ScanMode;
using firmware::ScanProfile;
using test::boardDir;
using test::hardwareGpio;
using test::profileError;
using test::scanError;
using test::TempDir;
using test::v4l2Main;

TEST(BoardProfile, LoadsTheSimBoard) {
  const BoardProfile p = loadBoardProfile(boardDir("sim"));
  EXPECT_EQ(p.name, "sim");
  EXPECT_EQ(p.file, boardDir("sim") / "board.toml");
  ASSERT_TRUE(p.sim.has_value());
  const sim::HeadConfig head = sim::loadHeadConfig(boardDir("sim") / "head.toml");
  EXPECT_EQ(p.sim->head, head);
  EXPECT_EQ(p.sim->head_file, boardDir("sim") / "head.toml");
  EXPECT_EQ(p.sim->scene, boardDir("sim") / "scenes" / "sphere_on_plane.toml");
  // The profile's line names are the head's.
  EXPECT_EQ(p.gpio.step.name, head.lines.step.name);
  EXPECT_EQ(p.gpio.dir.name, head.lines.dir.name);
  EXPECT_EQ(p.gpio.enable.name, head.lines.enable.name);
  EXPECT_EQ(p.gpio.light.name, head.lines.light.name);
  EXPECT_EQ(p.gpio.home.name, head.lines.home.name);
  ASSERT_TRUE(p.gpio.fault.has_value());
  EXPECT_EQ(p.gpio.fault->name, head.lines.fault.name);
  ASSERT_EQ(p.gpio.triggers.count("trigger"), 1U);
  EXPECT_EQ(p.gpio.triggers.at("trigger").name, head.lines.trigger.name);
  EXPECT_EQ(p.gpio.step.role, "step");
  // The firmware's stage has the head's step geometry.
  EXPECT_DOUBLE_EQ(p.stage.stepsPerDeg(), head.stage.full_steps_per_rev * head.stage.microsteps *
                                              head.stage.gear_ratio / 360.0);
  EXPECT_LT(p.stage.max_speed_deg_s, head.stage.max_speed_deg_s);
  ASSERT_EQ(p.cameras.size(), 2U);
  EXPECT_EQ(p.cameras[0].name, "main");
  EXPECT_EQ(p.cameras[1].name, "aux");
  for (const CameraProfile& c : p.cameras) {
    EXPECT_EQ(c.backend, CameraBackendKind::Sim);
    EXPECT_EQ(c.config.trigger, TriggerMode::GpioPulse);
    EXPECT_EQ(c.trigger_line, "trigger");
  }
  EXPECT_EQ(p.camera("aux").device, "aux");
  EXPECT_THROW(p.camera("side"), std::invalid_argument);
  const ScanProfile scan = readScanProfile(p);
  EXPECT_EQ(scan.mode, ScanMode::StopAndGo);
  EXPECT_DOUBLE_EQ(firmware::settleMs(p, scan), p.stage.settle_ms);
}

// board/sim's start angles put the main camera's view on the cylinder's high
// half for the high set and on the low half for the low set, away from the
// halves' edges, and both sets 180° apart.
TEST(BoardProfile, ScanDefaultsUseTheRightHalvesOfTheSimCylinder) {
  const BoardProfile p = loadBoardProfile(boardDir("sim"));
  const sim::VirtualHead head(p.sim->head, sim::Scene{}, 1);
  const sim::CameraModel& cam = head.cameraModel("main");
  const double margin = 10.0;  // degrees from a half's edge
  {
    const ScanProfile scan = readScanProfile(p);
    for (double z : {540.0, 580.0, 620.0}) {
      for (double u : {0.0, cam.width() - 1.0}) {
        const sim::Vec3 d = cam.rayDirection(u, cam.height() / 2.0);
        const sim::Vec3 x = cam.centre() + d * (z / d.z());
        const double alpha = head.projector().azimuthDeg(x);
        // A ray at azimuth α crosses the wall at β = α − ρ over each set's sweep.
        const double high_beta = sim::wrapDeg360(alpha - scan.high_start_deg);
        const double high_end = sim::wrapDeg360(high_beta - p.sim->head.projector.theta_high_deg);
        EXPECT_GT(std::min(high_beta, high_end), margin);
        EXPECT_LT(std::max(high_beta, high_end), 180.0 - margin);
        const double low_beta = sim::wrapDeg360(alpha - scan.low_start_deg);
        const double low_end = sim::wrapDeg360(low_beta - p.sim->head.projector.theta_low_deg);
        EXPECT_GT(std::min(low_beta, low_end), 180.0 + margin);
        EXPECT_LT(std::max(low_beta, low_end), 360.0 - margin);
      }
    }
    EXPECT_NEAR(sim::wrapDeg360(scan.high_start_deg - scan.low_start_deg), 180.0, 1e-9);
  }
}

TEST(BoardProfile, LoadsTheRpi5Profile) {
  const BoardProfile p = loadBoardProfile(boardDir("rpi5") / "board.toml");
  EXPECT_EQ(p.name, "rpi5");
  EXPECT_NE(p.description.find("Raspberry Pi 5"), std::string::npos);
  EXPECT_FALSE(p.sim.has_value());
  EXPECT_EQ(p.gpio.step.name, "GPIO17");
  EXPECT_TRUE(p.gpio.enable.active_low);
  EXPECT_FALSE(p.gpio.step.active_low);
  ASSERT_TRUE(p.gpio.fault.has_value());
  EXPECT_TRUE(p.gpio.fault->active_low);
  EXPECT_DOUBLE_EQ(p.stage.stepsPerDeg(), 200.0 * 16 * 45 / 360);
  ASSERT_EQ(p.cameras.size(), 1U);
  const CameraProfile& main = p.cameras[0];
  EXPECT_EQ(main.backend, CameraBackendKind::V4l2);
  EXPECT_EQ(main.device, "/dev/video0");
  EXPECT_EQ(main.config.bit_depth, 10);
  EXPECT_EQ(main.config.trigger, TriggerMode::GpioPulse);
  EXPECT_EQ(p.gpio.triggers.at(main.trigger_line).name, "GPIO23");
}

TEST(BoardProfile, DefaultsComeFromTheStructs) {
  TempDir dir;
  dir.write("board.toml", hardwareGpio() + v4l2Main());
  const BoardProfile p = loadBoardProfile(dir.path());
  const StageConfig stage;
  EXPECT_EQ(p.stage.microsteps, stage.microsteps);
  EXPECT_DOUBLE_EQ(p.stage.settle_ms, stage.settle_ms);
  EXPECT_EQ(p.stage.home_direction, stage.home_direction);
  EXPECT_FALSE(p.gpio.fault.has_value());
  EXPECT_EQ(p.gpio.enable.chip, "gpiochip0");
  EXPECT_EQ(p.gpio.enable.offset, 22);
  EXPECT_TRUE(p.gpio.enable.name.empty());
  EXPECT_EQ(p.cameras[0].config.bit_depth, 8);
  EXPECT_EQ(p.cameras[0].trigger_line, "trigger");
}

// The profile keeps [scan] for the firmware, which reads it with its defaults.
TEST(BoardProfile, ScanIsTheFirmwaresToRead) {
  TempDir dir;
  dir.write("board.toml", hardwareGpio() + v4l2Main() +
                              "[scan]\nsettle_ms = 42.5\nhigh_start_deg = 10.0\n"
                              "low_start_deg = 190.0\n");
  const BoardProfile p = loadBoardProfile(dir.path());
  EXPECT_EQ(p.scanTable().size(), 3u);
  const ScanProfile scan = readScanProfile(p);
  EXPECT_DOUBLE_EQ(firmware::settleMs(p, scan), 42.5);
  EXPECT_EQ(scan.frames_high, 25);
  EXPECT_EQ(scan.frames_low, 25);
  EXPECT_DOUBLE_EQ(scan.high_start_deg, 10.0);
  EXPECT_DOUBLE_EQ(scan.low_start_deg, 190.0);
}

// Each fault: the message names the file, the line and the key.
void expectFault(const drivers::ConfigError& e, const std::filesystem::path& file, int line,
                 const std::string& key, const std::string& words) {
  EXPECT_EQ(e.file(), file.string());
  EXPECT_EQ(e.line(), line) << e.what();
  EXPECT_EQ(e.key(), key) << e.what();
  const std::string what = e.what();
  EXPECT_NE(what.find(file.string() + ":" + std::to_string(line) + ": " + key), std::string::npos)
      << what;
  EXPECT_NE(what.find(words), std::string::npos) << what;
}

TEST(BoardProfileFaults, WrongType) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  expectFault(profileError(dir, "[board]\nname = 5\n"), file, 2, "board.name", "must be a string");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "width = \"wide\"\n"), file, 16,
              "camera[0].width", "must be an integer");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "[stage]\ngear_ratio = \"45\"\n"),
              file, 17, "stage.gear_ratio", "must be a number");
  std::string text = hardwareGpio();
  text.replace(text.find("step = { name = \"GPIO17\" }"), 26, "step = \"GPIO17\"");
  expectFault(profileError(dir, text + v4l2Main()), file, 5, "gpio.step", "must be a table");
}

TEST(BoardProfileFaults, UnknownKey) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  expectFault(profileError(dir, hardwareGpio() + "stepp = { name = \"GPIO5\" }\n" + v4l2Main()),
              file, 11, "gpio.stepp", "unknown key");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "focus = 3\n"), file, 16,
              "camera[0].focus", "unknown key");
  expectFault(
      scanError(dir, hardwareGpio() + v4l2Main() +
                         "[scan]\nhigh_start_deg = 0.0\nlow_start_deg = 180.0\nframes = 25\n"),
      file, 19, "scan.frames", "unknown key");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "[extras]\nx = 1\n"), file, 16,
              "extras", "unknown key");
  std::string text = hardwareGpio();
  text.replace(text.find("{ name = \"GPIO24\" }"), 19, "{ name = \"GPIO24\", pull = \"up\" }");
  expectFault(profileError(dir, text + v4l2Main()), file, 8, "gpio.light.pull", "unknown key");
}

TEST(BoardProfileFaults, MissingMainCamera) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  std::string aux = v4l2Main();
  aux.replace(aux.find("\"main\""), 6, "\"aux\"");
  expectFault(profileError(dir, hardwareGpio() + aux), file, 13, "camera[0].name",
              "the first camera must be \"main\"");
  // A missing top-level key is reported at line 1.
  expectFault(profileError(dir, hardwareGpio()), file, 1, "camera", "is required");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + v4l2Main()), file, 18,
              "camera[1].name", "twice");
}

TEST(BoardProfileFaults, CameraNamesThatCannotNameFilesOrUrls) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  for (const char* bad :
       {"Main2", "cam 90", "../x", "-cam", "_cam", "cam.90", "a23456789012345678901234567890123"}) {
    std::string second = v4l2Main();
    second.replace(second.find("\"main\""), 6, std::string("\"") + bad + "\"");
    expectFault(profileError(dir, hardwareGpio() + v4l2Main() + second), file, 18, "camera[1].name",
                "is not a camera name (1 to 32 of a-z 0-9 _ -");
  }
  EXPECT_TRUE(isCameraName("cam_90"));
  EXPECT_TRUE(isCameraName("side-left"));
  EXPECT_FALSE(isCameraName(""));
}

TEST(BoardProfileFaults, UnknownBackend) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  std::string usb = v4l2Main();
  usb.replace(usb.find("\"v4l2\""), 6, "\"usb\"");
  expectFault(profileError(dir, hardwareGpio() + usb), file, 14, "camera[0].backend",
              "unknown backend 'usb'");
  // A sim camera without the virtual head.
  std::string sim = v4l2Main();
  sim.replace(sim.find("\"v4l2\""), 6, "\"sim\"");
  expectFault(profileError(dir, hardwareGpio() + sim), file, 14, "camera[0].backend",
              "needs the virtual head");
  // A v4l2 camera has no software trigger.
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "trigger = \"software\"\n"), file, 16,
              "camera[0].trigger", "no software trigger");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "trigger = \"ttl\"\n"), file, 16,
              "camera[0].trigger", "unknown trigger 'ttl'");
}

TEST(BoardProfileFaults, TriggerLineNotInGpio) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "trigger_line = \"trigger_aux\"\n"),
              file, 16, "camera[0].trigger_line",
              "'trigger_aux' is not a trigger line in [gpio] (it has trigger)");
  // A trigger line named in [gpio] under trigger_<name> works.
  dir.write("board.toml", hardwareGpio() + "trigger_aux = { name = \"GPIO5\" }\n" + v4l2Main() +
                              "trigger_line = \"trigger_aux\"\n");
  const BoardProfile p = loadBoardProfile(dir.path());
  EXPECT_EQ(p.gpio.triggers.at("trigger_aux").name, "GPIO5");
  EXPECT_EQ(p.gpio.triggers.at("trigger_aux").role, "trigger_aux");
  // A free-running camera takes no trigger line.
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() +
                                    "trigger = \"free\"\ntrigger_line = \"trigger\"\n"),
              file, 17, "camera[0].trigger_line", "only with trigger = \"gpio\"");
}

TEST(BoardProfile, HowACameraStreams) {
  TempDir dir;
  // By default one frame per exposure, no latency.
  dir.write("board.toml", hardwareGpio() + v4l2Main());
  BoardProfile p = loadBoardProfile(dir.path());
  EXPECT_EQ(p.cameras[0].config.stream, FrameStream::PerExposure);
  EXPECT_EQ(p.cameras[0].image_latency_ms, 0.0);
  // A triggered camera behind a link that runs on its own clock.
  dir.write("board.toml",
            hardwareGpio() + v4l2Main() + "stream = \"continuous\"\nimage_latency_ms = 250.0\n");
  p = loadBoardProfile(dir.path());
  EXPECT_EQ(p.cameras[0].config.trigger, TriggerMode::GpioPulse);
  EXPECT_EQ(p.cameras[0].config.stream, FrameStream::Continuous);
  EXPECT_EQ(p.cameras[0].image_latency_ms, 250.0);
  // A free-running camera streams continuously whether it says so or not.
  dir.write("board.toml", hardwareGpio() + v4l2Main() + "trigger = \"free\"\n");
  p = loadBoardProfile(dir.path());
  EXPECT_EQ(p.cameras[0].config.stream, FrameStream::Continuous);
  EXPECT_EQ(toString(p.cameras[0].config.stream), "continuous");
}

TEST(BoardProfileFaults, StreamKeys) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "stream = \"burst\"\n"), file, 16,
              "camera[0].stream", "unknown stream 'burst'");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() +
                                    "trigger = \"free\"\nstream = \"per-exposure\"\n"),
              file, 17, "camera[0].stream", "a free-running camera streams continuously");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() + "image_latency_ms = 20.0\n"), file,
              16, "camera[0].image_latency_ms", "only with stream = \"continuous\"");
  expectFault(profileError(dir, hardwareGpio() + v4l2Main() +
                                    "stream = \"continuous\"\nimage_latency_ms = -1.0\n"),
              file, 17, "camera[0].image_latency_ms", "must be >= 0");
  // libcamera's software trigger asks for one frame: no continuous stream.
  std::string lib = v4l2Main();
  lib.replace(lib.find("\"v4l2\""), 6, "\"libcamera\"");
  expectFault(
      profileError(dir, hardwareGpio() + lib + "trigger = \"software\"\nstream = \"continuous\"\n"),
      file, 17, "camera[0].stream", "needs trigger = \"gpio\" or \"free\"");
}

TEST(BoardProfileFaults, BadLines) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  auto with = [](const std::string& from, const std::string& to) {
    std::string text = hardwareGpio();
    text.replace(text.find(from), from.size(), to);
    return text + v4l2Main();
  };
  expectFault(profileError(dir, with("{ name = \"GPIO17\" }",
                                     "{ name = \"GPIO17\", chip = \"gpiochip0\", offset = 17 }")),
              file, 5, "gpio.step.chip", "not both");
  expectFault(profileError(dir, with("{ name = \"GPIO17\" }", "{ offset = 17 }")), file, 5,
              "gpio.step.chip", "is required with offset");
  expectFault(profileError(dir, with("{ name = \"GPIO17\" }", "{ chip = \"gpiochip0\" }")), file, 5,
              "gpio.step.offset", "is required with chip");
  expectFault(
      profileError(dir, with("{ name = \"GPIO17\" }", "{ chip = \"gpiochip0\", offset = -1 }")),
      file, 5, "gpio.step.offset", "must be >= 0");
  expectFault(profileError(dir, with("{ name = \"GPIO17\" }", "{ active_low = true }")), file, 5,
              "gpio.step.name", "give the line's name");
  expectFault(
      profileError(dir, with("home = { name = \"GPIO25\" }", "home = { name = \"GPIO17\" }")), file,
      9, "gpio.home", "the same line as step");
  expectFault(profileError(dir, with("home = { name = \"GPIO25\" }\n", "")), file, 4, "gpio.home",
              "is required");
}

TEST(BoardProfileFaults, BadStageValues) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  const std::string base = hardwareGpio() + v4l2Main() + "[stage]\n";
  expectFault(profileError(dir, base + "microsteps = 0\n"), file, 17, "stage.microsteps",
              "must be in [1, 1024]");
  expectFault(profileError(dir, base + "max_speed_deg_s = 5.0\nstart_speed_deg_s = 6.0\n"), file,
              18, "stage.start_speed_deg_s", "must be <= max_speed_deg_s");
  expectFault(profileError(dir, base + "home_direction = 2\n"), file, 17, "stage.home_direction",
              "must be +1 or -1");
  expectFault(profileError(dir, base + "accel_deg_s2 = -80.0\n"), file, 17, "stage.accel_deg_s2",
              "must be > 0");
  expectFault(profileError(dir, base + "step_pulse_us = 150.0\n"), file, 17, "stage.step_pulse_us",
              "too short");
  expectFault(profileError(dir, base + "home_approach_speed_deg_s = 12.0\n"), file, 17,
              "stage.home_approach_speed_deg_s", "must be <= home_seek_speed_deg_s");
}

// Where the sets start depends on the home switch against the cylinder's
// halves: no default, every board says it.
TEST(BoardProfileFaults, TheSetsPlanNeedsItsStartAngles) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  const std::string base = hardwareGpio() + v4l2Main() + "[scan]\n";
  expectFault(scanError(dir, base), file, 16, "scan.high_start_deg",
              "is required with plan = \"sets\"");
  expectFault(scanError(dir, base + "high_start_deg = 10.0\n"), file, 16, "scan.low_start_deg",
              "is required with plan = \"sets\"");
}

TEST(BoardProfileFaults, BadScanValues) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  const std::string base = hardwareGpio() + v4l2Main() + "[scan]\n";
  expectFault(scanError(dir, base + "frames_high = 2\n"), file, 17, "scan.frames_high",
              "must be in [3, 1000]");
  expectFault(scanError(dir, base + "high_start_deg = 0.0\nlow_start_deg = 360.0\n"), file, 18,
              "scan.low_start_deg", "must be in [0, 360)");
  expectFault(scanError(dir, base + "mode = \"sweep\"\n"), file, 17, "scan.mode",
              "unknown mode 'sweep'");
}

// [scan] plan = "ring" (the 360° head): every camera needs its azimuths.
TEST(BoardProfile, RingPlanKeys) {
  TempDir dir;
  dir.write("board.toml", hardwareGpio() + v4l2Main() +
                              "azimuth_deg = [-20.0, -3.0]\n[scan]\nplan = \"ring\"\n"
                              "step_deg = 0.212\nhigh_half_start_deg = 10.0\n");
  const BoardProfile p = loadBoardProfile(dir.path());
  const ScanProfile scan = readScanProfile(p);
  EXPECT_EQ(scan.plan, PlanKind::Ring);
  EXPECT_DOUBLE_EQ(scan.step_deg, 0.212);
  EXPECT_DOUBLE_EQ(scan.high_half_start_deg, 10.0);
  ASSERT_TRUE(p.camera("main").azimuth_deg.has_value());
  EXPECT_DOUBLE_EQ((*p.camera("main").azimuth_deg)[0], -20.0);
  EXPECT_EQ(scan.frames_low, scan.frames_high);
  EXPECT_EQ(firmware::toString(scan.plan), "ring");
}

TEST(BoardProfileFaults, BadRingValues) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  const std::string base = hardwareGpio() + v4l2Main();
  expectFault(scanError(dir, base + "[scan]\nplan = \"ring\"\n"), file, 17, "scan.plan",
              "needs azimuth_deg");
  expectFault(profileError(dir, base + "azimuth_deg = [5.0, -3.0]\n"), file, 16,
              "camera[0].azimuth_deg", "lo < hi");
  expectFault(scanError(dir, base + "[scan]\nplan = \"spiral\"\n"), file, 17, "scan.plan",
              "unknown plan 'spiral'");
  expectFault(scanError(dir, base + "[scan]\nstep_deg = 0.2\n"), file, 17, "scan.step_deg",
              "only with plan = \"ring\"");
  expectFault(scanError(dir, base + "azimuth_deg = [-20.0, -3.0]\n[scan]\nplan = \"ring\"\n"
                                    "frames_high = 25\nframes_low = 20\n"),
              file, 20, "scan.frames_low", "must equal frames_high");
  expectFault(scanError(dir, base + "azimuth_deg = [-20.0, -3.0]\n[scan]\nplan = \"ring\"\n"
                                    "high_start_deg = 235.98\n"),
              file, 19, "scan.high_start_deg", "not used with plan = \"ring\"");
}

TEST(BoardProfileFaults, SyntaxError) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  const drivers::ConfigError e = profileError(dir, "[board]\nname = \"x\"\n[gpio\n");
  EXPECT_EQ(e.file(), file.string());
  EXPECT_EQ(e.line(), 3);
}

// [sim]: the head from a file or inline, cross-checked with the cameras.
std::string simBoard(const std::string& sim_section, const std::string& camera_extra = "") {
  return R"([board]
name = "sim-test"

[gpio]
step = { name = "step" }
dir = { name = "dir" }
enable = { name = "enable" }
light = { name = "light" }
home = { name = "home" }
trigger = { name = "trigger" }

[[camera]]
name = "main"
backend = "sim"
)" + camera_extra +
         "\n" + sim_section;
}

TEST(BoardProfile, SimHeadInline) {
  TempDir dir;
  dir.write("board.toml", simBoard("[sim]\nseed = 7\n[sim.head.noise]\nscale = 0.5\n"));
  const BoardProfile p = loadBoardProfile(dir.path());
  ASSERT_TRUE(p.sim.has_value());
  sim::HeadConfig expected = sim::defaultHeadConfig();
  expected.noise.scale = 0.5;
  EXPECT_EQ(p.sim->head, expected);
  EXPECT_TRUE(p.sim->head_file.empty());
  EXPECT_TRUE(p.sim->scene.empty());
  EXPECT_EQ(p.sim->seed, 7U);
}

TEST(BoardProfileFaults, BadSimSection) {
  TempDir dir;
  const auto file = dir.path() / "board.toml";
  expectFault(profileError(dir, simBoard("[sim.head.projector]\nradius_mm = -3.0\n")), file, 17,
              "sim.head.projector.radius_mm", "must be > 0");
  expectFault(profileError(dir, simBoard("[sim]\nhead = \"missing.toml\"\n")), file, 17, "sim.head",
              "no such file");
  expectFault(profileError(dir, simBoard("[sim]\nseed = 1\n")), file, 16, "sim.head",
              "is required");
  expectFault(
      profileError(dir, simBoard("[sim]\nhead = \"" + (boardDir("sim") / "head.toml").string() +
                                 "\"\nscene = \"nowhere.toml\"\n")),
      file, 18, "sim.scene", "no such file");
  // The cameras must be the head's, at its resolution.
  const std::string head = "[sim]\nhead = \"" + (boardDir("sim") / "head.toml").string() + "\"\n";
  expectFault(profileError(dir, simBoard(head, "device = \"side\"\n")), file, 15,
              "camera[0].device", "no camera 'side'");
  expectFault(profileError(dir, simBoard(head, "width = 640\nheight = 480\n")), file, 15,
              "camera[0].width", "is 1000x800");
  std::string v4l2 = simBoard(head);
  v4l2.replace(v4l2.find("\"sim\""), 5, "\"v4l2\"\ndevice = \"/dev/video0\"");
  expectFault(profileError(dir, v4l2), file, 14, "camera[0].backend",
              "a board with [sim] drives the virtual head");
}

}  // namespace
}  // namespace cylscan::drivers
