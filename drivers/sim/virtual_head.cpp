// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/virtual_head.hpp"

#include <stdexcept>
#include <string>

#include "drivers/sim/head_core.hpp"
#include "drivers/sim/sim_gpio.hpp"

namespace cylscan::sim {

VirtualHead::VirtualHead(HeadConfig config, Scene scene, std::uint64_t seed)
    : core_(std::make_unique<HeadCore>(std::move(config), std::move(scene), seed)),
      gpio_(std::make_unique<SimGpio>(*core_)) {}

VirtualHead::~VirtualHead() = default;

drivers::Clock& VirtualHead::clock() {
  return core_->clock;
}
drivers::GpioBackend& VirtualHead::gpio() {
  return *gpio_;
}

drivers::Camera& VirtualHead::camera(std::string_view name) {
  return *core_->cameras[static_cast<std::size_t>(core_->cameraIndex(name))];
}

std::vector<std::string> VirtualHead::cameraNames() const {
  std::vector<std::string> names;
  for (const CameraModel& m : core_->camera_models)
    names.push_back(m.params().name);
  return names;
}

const HeadConfig& VirtualHead::config() const {
  return core_->config;
}
const CylindricalProjector& VirtualHead::projector() const {
  return core_->projector;
}

const CameraModel& VirtualHead::cameraModel(std::string_view name) const {
  return core_->camera_models[static_cast<std::size_t>(core_->cameraIndex(name))];
}

const StageModel& VirtualHead::stage() const {
  return core_->stage;
}
bool VirtualHead::lightOn() const {
  return core_->lightAt(core_->clock.now());
}
void VirtualHead::setScene(Scene scene) {
  core_->setScene(std::move(scene));
}
Scene VirtualHead::scene() const {
  return core_->scene();
}

std::shared_ptr<const PixelGeometry> VirtualHead::pixelGeometry(std::string_view camera) {
  return core_->geometryFor(core_->cameraIndex(camera));
}

void VirtualHead::dropFrames(std::string_view camera, int count) {
  core_->cameras[static_cast<std::size_t>(core_->cameraIndex(camera))]->dropFrames(count);
}

void VirtualHead::delayNextFrame(std::string_view camera, std::chrono::nanoseconds delay) {
  core_->cameras[static_cast<std::size_t>(core_->cameraIndex(camera))]->delayNextFrame(delay);
}

void VirtualHead::corruptNextFrame(std::string_view camera) {
  core_->cameras[static_cast<std::size_t>(core_->cameraIndex(camera))]->corruptNextFrame();
}

void VirtualHead::loseSteps(int count) {
  if (count > 0) core_->stage.loseNextSteps(static_cast<std::uint64_t>(count));
}

void VirtualHead::setStageFault(bool fault) {
  core_->stage.setFault(fault, core_->clock.now());
  core_->clock.notifyEvent();
}

std::uint64_t VirtualHead::missedTriggers(std::string_view camera) const {
  return core_->cameras[static_cast<std::size_t>(core_->cameraIndex(camera))]->missedTriggers();
}

void VirtualHead::startTrace(std::size_t capacity) {
  core_->trace.start(capacity);
}

std::vector<VirtualHead::TracedEdge> VirtualHead::takeTrace() {
  std::size_t overflow = 0;
  const auto edges = core_->trace.take(&overflow);
  if (overflow > 0) {
    throw std::length_error("virtual head: the trace missed " + std::to_string(overflow) +
                            " edges (capacity " + std::to_string(edges.size()) + ")");
  }
  std::vector<TracedEdge> out;
  out.reserve(edges.size());
  for (const auto& e : edges)
    out.push_back({roleName(e.role), e.active, e.time});
  return out;
}

}  // namespace cylscan::sim
