// SPDX-License-Identifier: Apache-2.0
#include "drivers/board.hpp"

#include <chrono>

#include <gtest/gtest.h>

#include "drivers/sim/virtual_head.hpp"
#include "profile_support.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;
using test::boardDir;
using test::TempDir;

TEST(Board, SimBoardHandsOutTheVirtualHead) {
  Board board = Board::open(boardDir("sim"));
  EXPECT_EQ(board.profile().name, "sim");
  EXPECT_EQ(board.cameraNames(), (std::vector<std::string>{"main", "aux"}));
  ASSERT_NE(board.virtualHead(), nullptr);
  EXPECT_EQ(board.virtualHead()->scene().name, "sphere_on_plane");
  EXPECT_EQ(&board.clock(), &board.virtualHead()->clock());
  EXPECT_EQ(board.camera("aux").name(), "aux");
  EXPECT_THROW(board.camera("side"), std::invalid_argument);
}

// The firmware's view: lines by the profile's specs, steps move the stage.
TEST(Board, SimBoardLinesFromTheProfileDriveTheStage) {
  Board board = Board::open(boardDir("sim"));
  const GpioProfile& lines = board.profile().gpio;
  Clock& clock = board.clock();
  auto enable = board.gpio().requestOutput(lines.enable, true);
  auto dir = board.gpio().requestOutput(lines.dir, true);
  auto step = board.gpio().requestOutput(lines.step, false);
  const std::int64_t before = board.virtualHead()->stage().position();
  // Below the start rate: every pulse is followed.
  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(
      1e9 / (board.profile().stage.start_speed_deg_s * board.profile().stage.stepsPerDeg())));
  const int pulses = 5;
  for (int i = 0; i < pulses; ++i) {
    step->set(true);
    clock.sleepUntil(clock.now() + 5us);
    step->set(false);
    clock.sleepUntil(clock.now() + period);
  }
  EXPECT_EQ(board.virtualHead()->stage().position() - before, pulses);
  auto fault = board.gpio().requestInput(*lines.fault);
  EXPECT_FALSE(fault->get());
}

TEST(Board, AnUnknownPinIsAGpioErrorNamingIt) {
  Board board = Board::open(boardDir("sim"));
  LineSpec spec;
  spec.name = "GPIO99";
  spec.role = "light";
  try {
    board.gpio().requestOutput(spec, false);
    FAIL() << "an unknown pin was requested";
  } catch (const GpioError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("GPIO99"), std::string::npos) << what;
    EXPECT_NE(what.find("light"), std::string::npos) << what;
  }
}

TEST(Board, SimCamerasAreConfiguredFromTheProfileAndTriggeredByItsLine) {
  TempDir dir;
  // The sim board at a small resolution, through an inline head.
  dir.write("board.toml", R"([board]
name = "small-sim"
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
bit_depth = 12
exposure_us = 5000.0
[sim]
seed = 3
[[sim.head.camera]]
name = "main"
width = 64
height = 48
)");
  Board board = Board::open(dir.path(), boardDir("sim") / "scenes" / "isolated_objects.toml");
  EXPECT_EQ(board.virtualHead()->scene().name, "isolated_objects");
  const CameraProfile& profile = board.profile().camera("main");
  auto trigger =
      board.gpio().requestOutput(board.profile().gpio.triggers.at(profile.trigger_line), false);
  auto light = board.gpio().requestOutput(board.profile().gpio.light, true);
  Camera& cam = board.camera("main");
  cam.start();
  Clock& clock = board.clock();
  trigger->set(true);
  clock.sleepUntil(clock.now() + std::chrono::nanoseconds(
                                     static_cast<std::int64_t>(profile.trigger_pulse_us * 1000)));
  trigger->set(false);
  const std::optional<Frame> frame = cam.waitFrame(1s);
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->image.type(), CV_16UC1);  // bit_depth 12 from the profile
  EXPECT_EQ(frame->image.size(), cv::Size(64, 48));
  double max = 0;
  cv::minMaxLoc(frame->image, nullptr, &max);
  EXPECT_GT(max, 0.0);
  EXPECT_LE(max, 4095.0);
  EXPECT_FALSE(cam.waitFrame(10ms).has_value());  // one pulse, one frame
  cam.stop();
}

TEST(Board, ASceneIsOnlyForTheVirtualHead) {
  EXPECT_THROW(Board::open(boardDir("rpi5"), boardDir("sim") / "scenes" / "checkerboard.toml"),
               std::invalid_argument);
}

TEST(Board, AHardwareBoardWithoutItsDevicesSaysWhichIsMissing) {
  if (std::filesystem::exists("/dev/video0")) GTEST_SKIP() << "this machine has /dev/video0";
#ifdef CYLSCAN_HAVE_GPIOD
  try {
    Board::open(boardDir("rpi5"));
    FAIL() << "opened a board whose camera does not exist";
  } catch (const CameraError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/dev/video0"), std::string::npos) << what;
    EXPECT_NE(what.find("'main'"), std::string::npos) << what;
  }
#else
  // Without the gpiod backend the board cannot have its lines, and says so.
  try {
    Board::open(boardDir("rpi5"));
    FAIL() << "opened a hardware board without a GPIO backend";
  } catch (const GpioError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("rpi5"), std::string::npos) << what;
    EXPECT_NE(what.find("CYLSCAN_WITH_GPIOD"), std::string::npos) << what;
  }
#endif
}

#ifdef CYLSCAN_HAVE_GPIOD
// A libcamera camera that is not there (or a build without libcamera).
TEST(Board, AMissingLibcameraCameraIsAnErrorNamingIt) {
  if (std::filesystem::exists("/dev/media0")) GTEST_SKIP() << "this machine has media devices";
  TempDir dir;
  std::string text = test::hardwareGpio() + test::v4l2Main();
  text.replace(text.find("\"v4l2\""), 6, "\"libcamera\"");
  text.replace(text.find("\"/dev/video0\""), 13, "\"0\"");
  dir.write("board.toml", text);
  try {
    Board::open(dir.path());
    FAIL() << "opened a libcamera camera on a machine without cameras";
  } catch (const CameraError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'main'"), std::string::npos) << what;
#ifdef CYLSCAN_HAVE_LIBCAMERA
    EXPECT_NE(what.find("no such camera"), std::string::npos) << what;
#else
    EXPECT_NE(what.find("CYLSCAN_WITH_LIBCAMERA"), std::string::npos) << what;
#endif
  }
}
#endif

TEST(Board, ABadProfileIsAConfigError) {
  TempDir dir;
  dir.write("board.toml", "[board]\nname = \"x\"\nspeed = 3\n");
  EXPECT_THROW(Board::open(dir.path()), drivers::ConfigError);
  EXPECT_THROW(Board::open(dir.path() / "missing"), drivers::ConfigError);
}

}  // namespace
}  // namespace cylscan::drivers
