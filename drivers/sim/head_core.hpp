// SPDX-License-Identifier: Apache-2.0
// Internal state of a VirtualHead shared by its GPIO lines and cameras.
// Not part of the public API (include virtual_head.hpp).
#pragma once

#include <array>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string_view>
#include <vector>

#include "drivers/camera.hpp"
#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/edge_trace.hpp"
#include "drivers/sim/event_ring.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/renderer.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/stage.hpp"
#include "drivers/sim/virtual_clock.hpp"

namespace cylscan::sim {

enum class LineRole { Step, Dir, Enable, Trigger, Light, Home, Fault };
inline constexpr int kLineRoles = 7;
const char* roleName(LineRole role);
inline bool isInput(LineRole r) {
  return r == LineRole::Home || r == LineRole::Fault;
}

class VirtualCamera;

struct HeadCore {
  using Nanoseconds = std::chrono::nanoseconds;

  HeadCore(HeadConfig config, Scene scene, std::uint64_t seed);
  ~HeadCore();

  // Real-time path: a line's device-side level changed (no allocation, no lock).
  void drive(LineRole role, bool device_active);
  bool lightAt(Nanoseconds t) const;
  // When the light came on, if it is on at t.
  std::optional<Nanoseconds> lightOnSince(Nanoseconds t) const;
  const LineConfig& line(LineRole role) const;
  std::optional<LineRole> roleOf(std::string_view name) const;
  int cameraIndex(std::string_view name) const;  // throws std::invalid_argument

  // The traced optics of a camera for the current scene (traced on first use).
  std::shared_ptr<const PixelGeometry> geometryFor(int camera);
  void setScene(Scene scene);
  Scene scene() const;

  HeadConfig config;
  std::uint64_t seed;
  VirtualClock clock;
  CylindricalProjector projector;
  StageModel stage;
  NoiseTable noise;
  std::vector<CameraModel> camera_models;
  std::vector<std::unique_ptr<VirtualCamera>> cameras;
  std::array<bool, kLineRoles> requested{};
  std::array<bool, kLineRoles> level{};  // device-side active state of the outputs
  EdgeTrace<LineRole> trace;             // output edges, for golden traces

 private:
  struct LightSample {
    Nanoseconds time{0};
    bool on = false;
  };
  HistoryRing<LightSample, 4096> light_history_;
  // The index of the last light sample at or before t.
  std::uint64_t lightSampleAt(Nanoseconds t) const;
  mutable std::mutex scene_mutex_;
  Scene scene_;
  std::vector<std::shared_ptr<const PixelGeometry>> geometry_;
};

class VirtualCamera final : public drivers::Camera {
 public:
  using Nanoseconds = std::chrono::nanoseconds;
  VirtualCamera(HeadCore& core, int index);

  std::string name() const override;
  void configure(const drivers::CameraConfig& config) override;
  void start() override;
  void stop() override;
  void requestFrame() override;
  std::optional<drivers::Frame> waitFrame(Nanoseconds timeout) override;
  // The sensor's ranges ([[camera]] exposure_min_us, exposure_max_us,
  // gain_min, gain_max). configure() clamps a value outside them, as V4L2 and
  // libcamera sensor drivers do, so every backend behaves alike; a value that
  // no sensor takes (a negative exposure, a gain <= 0) is a CameraError.
  drivers::CameraControls controls() const override;

  // A trigger edge on the trigger line (real-time path); true when it started
  // an exposure.
  bool triggerEdge(Nanoseconds t);

  // Fault injection.
  void dropFrames(int count) { drop_ += count; }
  void delayNextFrame(Nanoseconds delay) { delay_ns_ += delay.count(); }
  void corruptNextFrame() { ++corrupt_; }
  std::uint64_t missedTriggers() const { return missed_; }

 private:
  struct Pending {
    Nanoseconds start{0};
    std::uint64_t sequence = 0;
  };
  bool expose(Nanoseconds start);
  cv::Mat renderExposure(const Pending& p);
  drivers::Frame render(const Pending& p);
  void tearIfAsked(cv::Mat& image);  // corruptNextFrame()
  Nanoseconds exposure() const;
  // A rolling shutter's delay from the first row's exposure to the last's.
  Nanoseconds rolling() const;
  // A Continuous stream: link frame k starts at the stream's origin + k
  // periods (1 / frame_rate_hz) and is delivered exposure + readout later.
  // Free-running, it is an exposure of its own; triggered, it shows the
  // latest exposure finished by its start (black before the first). Frames
  // nobody waits for are not delivered: the sequence (k) shows the gap.
  std::optional<drivers::Frame> waitLinkFrame(Nanoseconds timeout);

  HeadCore& core_;
  int index_;
  CameraParams params_;  // the configured sensor (exposure, gain, bit depth)
  drivers::TriggerMode mode_ = drivers::TriggerMode::GpioPulse;
  drivers::FrameStream stream_ = drivers::FrameStream::PerExposure;
  std::int64_t link_frame_ = -1;  // the last link frame delivered (Continuous)
  std::optional<Pending> shown_;  // the exposure the link shows (Continuous, triggered)
  cv::Mat shown_image_;           // its image, rendered once
  std::atomic<bool> started_{false};
  SpscQueue<Pending, 256> pending_;
  std::uint64_t next_sequence_ = 0;
  Nanoseconds last_start_{-1'000'000'000'000};
  Nanoseconds stream_origin_{0};
  std::atomic<int> drop_{0};
  std::atomic<int> corrupt_{0};
  std::atomic<std::int64_t> delay_ns_{0};
  std::atomic<std::uint64_t> missed_{0};
};

}  // namespace cylscan::sim
