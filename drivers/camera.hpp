// SPDX-License-Identifier: Apache-2.0
// Cameras behind a small interface: one backend per file (v4l2, libcamera, sim).
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

namespace cylscan::drivers {

// How an exposure is started. Neither V4L2 nor libcamera has a standard
// trigger control, so this is the camera's strategy, set by the board profile.
enum class TriggerMode {
  GpioPulse,   // a pulse on a GPIO line wired to the camera's trigger input
  Software,    // requestFrame() starts one exposure
  FreeRunning  // the camera streams; frames are matched by timestamp
};

// How frames reach the host.
//   PerExposure: one frame per exposure, numbered in order: a gap in the
//     sequence is a lost frame.
//   Continuous: the camera's link runs at its own frame rate and every frame
//     holds the latest finished exposure (a camera behind an HDMI or analogue
//     capture bridge, a UVC camera that repeats its last triggered image, and
//     every free-running camera). A gap is a frame nobody read, and the frame
//     of an exposure is the first one stamped at least the camera's image
//     latency after its trigger.
enum class FrameStream { PerExposure, Continuous };

struct CameraConfig {
  int width = 0;  // 0: the backend's default
  int height = 0;
  int bit_depth = 8;       // 8, 10, 12 or 16 significant bits
  double exposure_us = 0;  // 0: the backend's default
  double gain = 1.0;
  TriggerMode trigger = TriggerMode::GpioPulse;
  FrameStream stream = FrameStream::PerExposure;  // Continuous whenever trigger is FreeRunning
};

struct Frame {
  cv::Mat image;  // CV_8UC1 or CV_16UC1 (counts unscaled)
  // Increments by one per frame: per exposure (a gap is a lost frame), or
  // per frame of a Continuous link (a gap is a frame nobody read).
  std::uint64_t sequence = 0;
  // Start of exposure, CLOCK_MONOTONIC (or virtual); for a Continuous stream,
  // the start of the link's frame.
  std::chrono::nanoseconds timestamp{0};
};

// One numeric control: its value as configured and the range the camera accepts.
struct ControlRange {
  double value = 0, min = 0, max = 0;
};
// exposure_us in microseconds, gain as a linear factor (1 = unity), the units of CameraConfig.
struct CameraControls {
  ControlRange exposure_us;
  ControlRange gain;
};

class CameraError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Camera {
 public:
  virtual ~Camera() = default;
  virtual std::string name() const = 0;
  // Every backend clamps exposure_us and gain into the ranges controls()
  // reports, as the sensor drivers do, rather than refusing them: a caller
  // that must refuse a value out of range compares it with controls() first.
  virtual void configure(const CameraConfig& config) = 0;
  // The exposure and gain controls, valid after configure(): each value is
  // what the camera actually uses, after its own clamping and quantisation,
  // and min/max the range it accepts. A camera without such a control
  // reports min == max == value.
  virtual CameraControls controls() const = 0;
  virtual void start() = 0;
  virtual void stop() = 0;
  // Starts one exposure (TriggerMode::Software only).
  virtual void requestFrame() = 0;
  // Waits up to `timeout` for the next frame; nullopt on timeout.
  virtual std::optional<Frame> waitFrame(std::chrono::nanoseconds timeout) = 0;
};

}  // namespace cylscan::drivers
