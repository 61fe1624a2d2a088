// SPDX-License-Identifier: Apache-2.0
// A board: the backends its profile chooses, owned in one place. Firmware asks
// it for the GPIO backend, the cameras by name and the clock, and never learns
// which backends they are; only tests and `cylscan simulate` look at the
// virtual head behind a sim board.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/board_profile.hpp"
#include "drivers/camera.hpp"
#include "drivers/clock.hpp"
#include "drivers/gpio.hpp"

namespace cylscan::sim {
class VirtualHead;
}

namespace cylscan::drivers {

class Board {
 public:
  // Opens the board of a profile folder (board/<name>) or of a board.toml:
  // loads the profile, constructs its backends and configures every camera
  // with its profile settings (not started). `scene` replaces the virtual
  // head's default scene (an error on a hardware board).
  // Throws ConfigError for a bad profile, GpioError / CameraError when a
  // backend cannot be opened or was not built.
  static Board open(const std::filesystem::path& profile,
                    const std::optional<std::filesystem::path>& scene = std::nullopt);
  // The same from a profile already loaded (and perhaps adjusted: `cylscan
  // simulate` renders on the virtual head at the resolution it is asked for).
  static Board open(BoardProfile profile);

  Board(Board&&) noexcept;
  Board& operator=(Board&&) noexcept;
  Board(const Board&) = delete;
  Board& operator=(const Board&) = delete;
  ~Board();

  const BoardProfile& profile() const { return profile_; }
  GpioBackend& gpio() { return *gpio_; }
  Clock& clock() { return *clock_; }
  // Throws std::invalid_argument naming the camera when the board has none of that name.
  Camera& camera(std::string_view name);
  std::vector<std::string> cameraNames() const;  // profile order, "main" first

  // The virtual head behind a sim board; nullptr on hardware. For tests and
  // `simulate` only: firmware must not branch on it.
  sim::VirtualHead* virtualHead() { return head_.get(); }

 private:
  // Defined beside openSim: a build without the virtual head has no
  // VirtualHead destructor for board.cpp to call.
  struct HeadDeleter {
    void operator()(sim::VirtualHead* head) const;
  };

  Board() = default;
  static Board openWith(BoardProfile profile, const std::optional<std::filesystem::path>& scene);
  // drivers/board_sim.cpp; without the virtual head, drivers/board_sim_absent.cpp.
  void openSim(const std::optional<std::filesystem::path>& scene);
  void openHardware();

  BoardProfile profile_;
  std::unique_ptr<sim::VirtualHead, HeadDeleter> head_;  // sim boards
  std::unique_ptr<GpioBackend> own_gpio_;                // hardware boards
  std::unique_ptr<Clock> own_clock_;                     // hardware boards
  std::vector<std::unique_ptr<Camera>> own_cameras_;     // hardware boards
  GpioBackend* gpio_ = nullptr;
  Clock* clock_ = nullptr;
  std::vector<std::pair<std::string, Camera*>> cameras_;  // by profile name
};

}  // namespace cylscan::drivers
