// SPDX-License-Identifier: Apache-2.0
// The virtual scanning head: the cylindrical projector, the rotation stage,
// the cameras and a scene, behind the same driver interfaces as the hardware
// (drivers::GpioBackend, drivers::Camera, drivers::Clock). See docs/virtual-head.md.
//
// Threading: output lines' set() is allocation- and lock-free; cameras and
// input lines may be waited on from the driving thread or another. The clock
// is a discrete-event clock: threads that take part hold a
// drivers::ClockThread (see virtual_clock.hpp); with pace_real_time it is the
// real monotonic time.
// The head must outlive the lines and camera references it hands out.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/camera.hpp"
#include "drivers/clock.hpp"
#include "drivers/gpio.hpp"
#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/renderer.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/stage.hpp"

namespace cylscan::sim {

struct HeadCore;
class SimGpio;

class VirtualHead {
 public:
  VirtualHead(HeadConfig config, Scene scene, std::uint64_t seed = 1);
  ~VirtualHead();
  VirtualHead(const VirtualHead&) = delete;
  VirtualHead& operator=(const VirtualHead&) = delete;

  // The driver interfaces.
  drivers::Clock& clock();
  drivers::GpioBackend& gpio();
  drivers::Camera& camera(std::string_view name);  // throws std::invalid_argument
  std::vector<std::string> cameraNames() const;

  // The model, for truth and inspection.
  const HeadConfig& config() const;
  const CylindricalProjector& projector() const;
  const CameraModel& cameraModel(std::string_view name) const;
  const StageModel& stage() const;
  bool lightOn() const;
  void setScene(Scene scene);  // between acquisitions
  Scene scene() const;
  // Per-pixel truth of a camera for the current scene (first hits, lit/shadow flags).
  std::shared_ptr<const PixelGeometry> pixelGeometry(std::string_view camera);

  // Fault injection for tests.
  void dropFrames(std::string_view camera, int count);  // exposed but never delivered
  void delayNextFrame(std::string_view camera, std::chrono::nanoseconds delay);
  void corruptNextFrame(std::string_view camera);  // lower half garbage
  void loseSteps(int count);                       // the next step pulses are lost
  void setStageFault(bool fault);                  // the fault input
  std::uint64_t missedTriggers(std::string_view camera) const;

  // Golden traces: every change of an output line (its role, the level the
  // device sees, the virtual time), from startTrace() to takeTrace(). Call
  // both while no thread drives the lines; recording itself neither
  // allocates nor locks.
  struct TracedEdge {
    std::string line;  // the role: step, dir, enable, trigger, light
    bool active = false;
    std::chrono::nanoseconds time{0};
  };
  void startTrace(std::size_t capacity = 1 << 16);
  // Throws std::length_error when more edges came than the capacity.
  std::vector<TracedEdge> takeTrace();

 private:
  std::unique_ptr<HeadCore> core_;
  std::unique_ptr<SimGpio> gpio_;
};

}  // namespace cylscan::sim
