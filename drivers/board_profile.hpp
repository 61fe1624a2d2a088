// SPDX-License-Identifier: Apache-2.0
// The board profile (board/<name>/board.toml): which backends drive the head,
// where its GPIO lines are, its stage, its cameras and, for the virtual head,
// its model; its [scan] table is the firmware's (firmware/scan_profile.hpp). Format:
// board/README.md.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "common/vocabulary.hpp"
#include "drivers/camera.hpp"
#include "drivers/gpio.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/stage_config.hpp"

namespace cylscan::drivers {

// [gpio]: every line as a LineSpec (by name, or by chip and offset), its role set.
struct GpioProfile {
  LineSpec step, dir, enable, light, home;
  std::optional<LineSpec> fault;
  std::map<std::string, LineSpec> triggers;  // by key: "trigger", "trigger_aux", ...
};

enum class CameraBackendKind { Sim, V4l2, Libcamera };

// [[camera]]
struct CameraProfile {
  std::string name;  // "main" first
  CameraBackendKind backend = CameraBackendKind::Sim;
  // v4l2: the device path; libcamera: the camera id or index; sim: the head's
  // camera (default: the same name).
  std::string device;
  CameraConfig config;       // width, height, bit_depth, exposure_us, gain, trigger
  std::string trigger_line;  // the [gpio] trigger key when config.trigger is GpioPulse
  double trigger_pulse_us = 10.0;
  double frame_rate_hz = 30.0;  // the most frames a second it delivers (continuous mode's pace)
  // config.stream Continuous: from the trigger (a free-running camera: the
  // end of the settle) to the first frame stamped late enough to hold the
  // new exposure; earlier frames are passed over.
  double image_latency_ms = 0.0;
  // The projector azimuths [lo, hi] (degrees about the projector axis) that its
  // working volume spans: what the ring planner needs ([scan] plan = "ring").
  std::optional<std::array<double, 2>> azimuth_deg;
};

// [sim]: the virtual head.
struct SimProfile {
  sim::HeadConfig head;
  std::filesystem::path head_file;  // the head file, or empty when [sim] holds the head inline
  std::filesystem::path scene;      // the default scene file
  std::uint64_t seed = 1;
};

struct BoardProfile {
  std::filesystem::path file;  // the board.toml read
  std::string name;
  std::string description;
  GpioProfile gpio;
  StageConfig stage;
  std::vector<CameraProfile> cameras;  // "main" first
  // The parsed file, shared by the copies of the profile. It holds [scan],
  // unread here: how to scan is the firmware's policy (firmware/scan_profile.hpp),
  // and its nodes keep their lines for the firmware's messages.
  std::shared_ptr<const toml::table> document;
  std::optional<SimProfile> sim;  // set exactly when the cameras are the virtual head's

  // Throws std::invalid_argument naming the camera when there is none of that name.
  const CameraProfile& camera(std::string_view name) const;
  // The [scan] table; an empty one when the file has none.
  const toml::table& scanTable() const;
};

std::string_view toString(CameraBackendKind backend);
std::string_view toString(TriggerMode trigger);
std::string_view toString(FrameStream stream);

// Whether this build has the virtual head (configured with CYLSCAN_WITH_SIM,
// the default). Without it, a profile whose cameras are "sim" or that has a
// [sim] table is refused with kNoVirtualHead, as is Board::open of such a profile.
bool virtualHeadBuilt();
inline constexpr std::string_view kNoVirtualHead =
    "this build has no virtual head (CYLSCAN_WITH_SIM=OFF)";

// Reads `dir`/board.toml (or the file itself when given one). Every fault
// throws ConfigError (drivers/toml_reader.hpp, a std::invalid_argument) naming the file, the line
// and the key; unknown keys are faults. Files named in it are relative to its folder.
BoardProfile loadBoardProfile(const std::filesystem::path& dir_or_file);
// The same from a parsed table; `file` names it in messages and anchors relative
// paths. The table is taken by value: toml++ keeps source lines only when a
// table is moved, not copied.
BoardProfile parseBoardProfile(toml::table table, const std::filesystem::path& file);

}  // namespace cylscan::drivers
