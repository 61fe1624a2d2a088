// SPDX-License-Identifier: Apache-2.0
// The virtual head behind a sim board (CYLSCAN_WITH_SIM); a build without it
// compiles drivers/board_sim_absent.cpp instead.
#include <memory>
#include <utility>

#include "drivers/board.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/virtual_head.hpp"

namespace cylscan::drivers {

bool virtualHeadBuilt() {
  return true;
}

void Board::HeadDeleter::operator()(sim::VirtualHead* head) const {
  std::default_delete<sim::VirtualHead>{}(head);
}

void Board::openSim(const std::optional<std::filesystem::path>& scene) {
  const SimProfile& s = *profile_.sim;
  sim::Scene world;
  world.name = "empty";
  if (scene) {
    world = sim::loadScene(*scene);
  } else if (!s.scene.empty()) {
    world = sim::loadScene(s.scene);
  }
  head_.reset(std::make_unique<sim::VirtualHead>(s.head, std::move(world), s.seed).release());
  gpio_ = &head_->gpio();
  clock_ = &head_->clock();
  for (const CameraProfile& c : profile_.cameras) {
    cameras_.emplace_back(c.name, &head_->camera(c.device));
  }
}

}  // namespace cylscan::drivers
