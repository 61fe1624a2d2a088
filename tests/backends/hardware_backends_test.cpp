// SPDX-License-Identifier: Apache-2.0
// The hardware backends where this machine has no hardware: their failures
// must be clear errors naming what is missing.
#include <chrono>
#include <filesystem>

#include <gtest/gtest.h>

#include "drivers/clock_monotonic.hpp"
#include "profile_support.hpp"
#ifdef CYLSCAN_HAVE_GPIOD
#include "drivers/gpio_gpiod.hpp"
#endif
#ifdef CYLSCAN_HAVE_V4L2
#include "drivers/camera_v4l2.hpp"
#endif

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;

#ifdef CYLSCAN_HAVE_GPIOD
TEST(GpiodBackend, NoChipsIsAnErrorNamingTheLineAndTheFolder) {
  test::TempDir dir;
  GpiodBackend gpio(dir.path());
  LineSpec spec;
  spec.name = "GPIO17";
  spec.role = "step";
  try {
    gpio.requestOutput(spec, false);
    FAIL() << "requested a line without chips";
  } catch (const GpioError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("step line 'GPIO17'"), std::string::npos) << what;
    EXPECT_NE(what.find(dir.path().string()), std::string::npos) << what;
  }
  // Files that merely look like chips are not chips.
  dir.write("gpiochip0", "not a device");
  GpiodBackend fake(dir.path());
  EXPECT_TRUE(fake.chips().empty());
  EXPECT_THROW(fake.requestInput(spec), GpioError);
}

TEST(GpiodBackend, AMissingFolderIsAnError) {
  GpiodBackend gpio("/nonexistent/cylscan");
  EXPECT_THROW(gpio.chips(), GpioError);
}
#endif

#ifdef CYLSCAN_HAVE_V4L2
TEST(V4l2Camera, AMissingDeviceIsAnErrorNamingIt) {
  try {
    V4l2Camera cam("main", "/nonexistent/video0");
    FAIL() << "opened a missing device";
  } catch (const CameraError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'main'"), std::string::npos) << what;
    EXPECT_NE(what.find("/nonexistent/video0"), std::string::npos) << what;
  }
}

TEST(V4l2Camera, ANonVideoDeviceIsRefused) {
  try {
    V4l2Camera cam("aux", "/dev/null");
    FAIL() << "/dev/null taken for a camera";
  } catch (const CameraError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/dev/null"), std::string::npos) << what;
    EXPECT_NE(what.find("VIDIOC_QUERYCAP"), std::string::npos) << what;
  }
}
#endif

TEST(MonotonicClock, SleepsUntilTheDeadline) {
  MonotonicClock clock;
  const auto start = clock.now();
  EXPECT_GT(start.count(), 0);
  const auto deadline = start + 2ms;
  clock.sleepUntil(deadline);
  EXPECT_GE(clock.now(), deadline);
  clock.sleepUntil(start);  // past: returns at once
  EXPECT_GE(clock.now(), start);
}

}  // namespace
}  // namespace cylscan::drivers
