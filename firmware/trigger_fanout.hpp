// SPDX-License-Identifier: Apache-2.0
// The cameras' trigger as one output for the executor: a pulse on every GPIO
// trigger line in use, and an exposure request to every software-triggered
// camera on the rising edge (several cameras, one instant).
#pragma once

#include <memory>
#include <vector>

#include "drivers/camera.hpp"
#include "drivers/gpio.hpp"

namespace cylscan::firmware {

class TriggerFanout final : public drivers::OutputLine {
 public:
  void addLine(std::unique_ptr<drivers::OutputLine> line) { lines_.push_back(std::move(line)); }
  void addSoftwareCamera(drivers::Camera& camera) { software_.push_back(&camera); }
  void clearSoftwareCameras() { software_.clear(); }
  bool empty() const { return lines_.empty() && software_.empty(); }

  void set(bool active) override {
    for (auto& line : lines_)
      line->set(active);
    if (active) {
      for (drivers::Camera* camera : software_)
        camera->requestFrame();
    }
  }

 private:
  std::vector<std::unique_ptr<drivers::OutputLine>> lines_;
  std::vector<drivers::Camera*> software_;
};

}  // namespace cylscan::firmware
