// SPDX-License-Identifier: Apache-2.0
// A camera through the kernel's V4L2 capture API (/dev/videoN): single-planar
// mmap streaming of monochrome formats (GREY, Y10, Y12, Y16, Y10P, Y12P),
// manual exposure and gain through controls. V4L2 has no software trigger:
// GpioPulse expects the sensor in external-trigger mode (set up by the board:
// device tree or driver parameter), FreeRunning streams.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "drivers/camera.hpp"
#include "drivers/mono_image.hpp"
#include "drivers/posix_io.hpp"

namespace cylscan::drivers {

// What configure() obtained from the device.
struct V4l2Negotiated {
  MonoFormat format;  // the chosen pixel format (its bits may differ from the request)
  int width = 0;
  int height = 0;
  std::size_t stride = 0;  // bytes per line
  double exposure_us = 0;  // as set (0: left to the device)
  std::int64_t gain_value = 0;
  // The exposure (µs) and gain (factor of the control's default) as set, or
  // as the device had them when left to it, and the device's ranges.
  CameraControls controls;
  std::vector<std::string> notes;  // what differs from the request, e.g. clamped controls
};

class V4l2Camera final : public Camera {
 public:
  // Opens the device and checks that it captures video with streaming I/O.
  // Throws CameraError naming the camera and the device.
  V4l2Camera(std::string name, std::filesystem::path device);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  std::string name() const override { return name_; }
  void configure(const CameraConfig& config) override;
  void start() override;
  void stop() override;
  void requestFrame() override;  // always throws: V4L2 has no software trigger
  // From VIDIOC_QUERYCTRL of V4L2_CID_EXPOSURE_ABSOLUTE and V4L2_CID_GAIN (or
  // V4L2_CID_ANALOGUE_GAIN), read in configure(); configure() clamps to them.
  CameraControls controls() const override { return negotiated_.controls; }
  // A timeout, or an error from the stream, restarts the stream once per call
  // (a zero timeout only polls and restarts nothing).
  std::optional<Frame> waitFrame(std::chrono::nanoseconds timeout) override;

  const V4l2Negotiated& negotiated() const { return negotiated_; }

 private:
  [[noreturn]] void fail(const std::string& what) const;
  [[noreturn]] void failErrno(const std::string& what) const;
  void setFormat(const CameraConfig& config);
  void setControls(const CameraConfig& config);
  void queueAll();
  void restartStream();
  void releaseBuffers();
  // One DQBUF: a frame, nullopt for nothing ready or a lost frame; throws on errors.
  std::optional<Frame> dequeue();

  std::string name_;
  std::filesystem::path device_;
  UniqueFd fd_;
  std::optional<CameraConfig> config_;
  V4l2Negotiated negotiated_;
  std::vector<MemoryMap> buffers_;  // one mapping per device buffer
  bool streaming_ = false;
  SequenceCounter sequence_;
};

}  // namespace cylscan::drivers
