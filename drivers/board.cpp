// SPDX-License-Identifier: Apache-2.0
#include "drivers/board.hpp"

#include <stdexcept>
#include <utility>

#include "drivers/clock_monotonic.hpp"
#ifdef CYLSCAN_HAVE_GPIOD
#include "drivers/gpio_gpiod.hpp"
#endif
#ifdef CYLSCAN_HAVE_V4L2
#include "drivers/camera_v4l2.hpp"
#endif
#ifdef CYLSCAN_HAVE_LIBCAMERA
#include "drivers/camera_libcamera.hpp"
#endif

namespace cylscan::drivers {

namespace {

[[noreturn, maybe_unused]] void notBuilt(const BoardProfile& p, const std::string& what,
                                         const std::string& option) {
  throw CameraError("board '" + p.name + "' (" + p.file.string() + "): " + what +
                    ", which this build lacks (configured with " + option +
                    "=OFF or without its library)");
}

std::unique_ptr<Camera> makeCamera(const BoardProfile& p, const CameraProfile& c) {
  switch (c.backend) {
    case CameraBackendKind::V4l2:
#ifdef CYLSCAN_HAVE_V4L2
      return std::make_unique<V4l2Camera>(c.name, c.device);
#else
      notBuilt(p, "camera '" + c.name + "' needs the v4l2 backend", "a Linux target");
#endif
    case CameraBackendKind::Libcamera:
#ifdef CYLSCAN_HAVE_LIBCAMERA
      return std::make_unique<LibcameraCamera>(c.name, c.device);
#else
      notBuilt(p, "camera '" + c.name + "' needs the libcamera backend", "CYLSCAN_WITH_LIBCAMERA");
#endif
    case CameraBackendKind::Sim:
      break;
  }
  throw CameraError("board '" + p.name + "': camera '" + c.name +
                    "' is a virtual head camera on a hardware board");
}

}  // namespace

Board::Board(Board&&) noexcept = default;
Board& Board::operator=(Board&&) noexcept = default;
Board::~Board() = default;

Board Board::open(const std::filesystem::path& profile,
                  const std::optional<std::filesystem::path>& scene) {
  return openWith(loadBoardProfile(profile), scene);
}

Board Board::open(BoardProfile profile) {
  return openWith(std::move(profile), std::nullopt);
}

Board Board::openWith(BoardProfile profile, const std::optional<std::filesystem::path>& scene) {
  Board b;
  b.profile_ = std::move(profile);
  if (b.profile_.sim) {
    b.openSim(scene);
  } else {
    if (scene) {
      throw std::invalid_argument("board '" + b.profile_.name +
                                  "' drives hardware: a scene is only for the virtual head");
    }
    b.openHardware();
  }
  for (const CameraProfile& c : b.profile_.cameras)
    b.camera(c.name).configure(c.config);
  return b;
}

void Board::openHardware() {
#ifdef CYLSCAN_HAVE_GPIOD
  own_gpio_ = std::make_unique<GpiodBackend>();
#else
  throw GpioError("board '" + profile_.name + "' (" + profile_.file.string() +
                  "): its GPIO lines need the gpiod backend, which this build lacks "
                  "(configured with CYLSCAN_WITH_GPIOD=OFF or without libgpiod v2)");
#endif
  own_clock_ = std::make_unique<MonotonicClock>();
  gpio_ = own_gpio_.get();
  clock_ = own_clock_.get();
  for (const CameraProfile& c : profile_.cameras) {
    own_cameras_.push_back(makeCamera(profile_, c));
    cameras_.emplace_back(c.name, own_cameras_.back().get());
  }
}

Camera& Board::camera(std::string_view name) {
  for (auto& [n, cam] : cameras_) {
    if (n == name) return *cam;
  }
  throw std::invalid_argument("board '" + profile_.name + "': no camera '" + std::string(name) +
                              "' (it has " +
                              [this] {
                                std::string list;
                                for (const auto& [n, c] : cameras_) {
                                  list += (list.empty() ? "" : ", ") + n;
                                }
                                return list;
                              }() +
                              ")");
}

std::vector<std::string> Board::cameraNames() const {
  std::vector<std::string> names;
  for (const auto& [n, c] : cameras_)
    names.push_back(n);
  return names;
}

}  // namespace cylscan::drivers
