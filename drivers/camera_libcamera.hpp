// SPDX-License-Identifier: Apache-2.0
// A camera through libcamera (0.3): one raw monochrome stream, manual
// exposure and analogue gain set in every request (auto exposure off), frames
// handed from libcamera's completion thread to waitFrame() through a bounded
// queue. Software trigger: requestFrame() queues one request; FreeRunning and
// GpioPulse (the sensor in external-trigger mode) keep all requests queued.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/camera.hpp"
#include "drivers/mono_image.hpp"

namespace cylscan::drivers {

// What configure() obtained from the camera.
struct LibcameraNegotiated {
  MonoFormat format;
  int width = 0;
  int height = 0;
  std::size_t stride = 0;
  double exposure_us = 0;  // as set (0: left to the camera)
  double gain = 0;         // analogue gain as set (0: left to the camera)
  // ExposureTime (µs) and AnalogueGain as set, with the bounds of their
  // ControlInfo; an exposure left to the camera reports the control's default.
  CameraControls controls;
  std::vector<std::string> notes;  // what differs from the request
};

class LibcameraCamera final : public Camera {
 public:
  // `id`: a libcamera camera id, or its index in the camera manager's list
  // ("0"). Acquires the camera; throws CameraError naming it.
  LibcameraCamera(std::string name, std::string id);
  ~LibcameraCamera() override;
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  std::string name() const override;
  void configure(const CameraConfig& config) override;
  void start() override;
  void stop() override;
  void requestFrame() override;
  // configure() clamps to the ranges of ExposureTime and AnalogueGain.
  CameraControls controls() const override;
  std::optional<Frame> waitFrame(std::chrono::nanoseconds timeout) override;

  const LibcameraNegotiated& negotiated() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cylscan::drivers
