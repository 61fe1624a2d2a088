// SPDX-License-Identifier: Apache-2.0
// The cameras' exposure and gain as set through the API, kept in the data
// directory so that a restart (or a power cut) does not lose a head's
// set-up: `cameras.json`, {"<camera>": {"exposure_us": x, "gain": g}},
// written atomically. A camera or a control that is absent keeps the board
// profile's value.
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include "drivers/camera.hpp"

namespace cylscan::firmware {

struct CameraControlSetting {
  std::optional<double> exposure_us;
  std::optional<double> gain;
};
using CameraControlSettings = std::map<std::string, CameraControlSetting, std::less<>>;

// The settings in `file`; none when it does not exist. std::runtime_error
// naming the file and what is wrong when it cannot be read or is not of
// the shape above.
CameraControlSettings readCameraSettings(const std::filesystem::path& file);

// Writes `settings` to `file` atomically (temporary, fsync, rename).
void writeCameraSettings(const std::filesystem::path& file, const CameraControlSettings& settings);

// `config` with the setting's values in place of its own.
drivers::CameraConfig withSetting(drivers::CameraConfig config,
                                  const CameraControlSetting& setting);

}  // namespace cylscan::firmware
