// SPDX-License-Identifier: Apache-2.0
// The virtual head's physical parameters (board/sim/head.toml): projector,
// stage, cameras, noise and the names of its GPIO lines.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/stage.hpp"

namespace cylscan::sim {

struct LineConfig {
  std::string name;
  bool active_low = false;  // the device's electrical polarity
  bool operator==(const LineConfig&) const = default;
};

struct LinesConfig {
  LineConfig step{"step"}, dir{"dir"}, enable{"enable"}, trigger{"trigger"}, light{"light"},
      home{"home"}, fault{"fault"};
  bool operator==(const LinesConfig&) const = default;
};

struct NoiseConfig {
  double scale = 0.3;  // multiplies the shot and read noise (see docs/virtual-head.md)
  double reference_exposure_us = 10000.0;  // exposure at which light levels are given
  bool operator==(const NoiseConfig&) const = default;
};

struct RenderConfig {
  int exposure_samples = 5;   // sub-samples of the pattern over an exposure while the stage moves
  int board_supersample = 2;  // s × s rays per pixel for scenes with a checkerboard
  int threads = 0;            // 0: up to 2
  bool pace_real_time = false;
  bool operator==(const RenderConfig&) const = default;
};

// Faults present from power-up ([faults]), for tests that run the firmware on
// the head through a board profile (the daemon's fault-injection tests): the
// same faults as VirtualHead's injection calls, counted from the start.
struct FaultConfig {
  std::string camera = "main";      // the camera the frame faults apply to
  int drop_frames = 0;              // its first frames: exposed, never delivered
  double delay_first_frame_ms = 0;  // its first frame arrives this much later
  int corrupt_frames = 0;           // its first frames: the lower half garbage
  int lose_steps_after = 0;         // after this many step pulses (homing included) ...
  int lose_steps = 0;               // ... this many are lost (the stage stalls)
  bool home_switch = true;          // false: the home switch never fires
  bool operator==(const FaultConfig&) const = default;
};

struct HeadConfig {
  ProjectorParams projector;
  StageParams stage;
  std::vector<CameraParams> cameras;  // "main" first
  NoiseConfig noise;
  LinesConfig lines;
  RenderConfig render;
  FaultConfig faults;
  bool operator==(const HeadConfig&) const = default;
};

// The built-in head: board/sim/head.toml's values without its imperfections
// (the ideal head the sim's own unit tests and inline test heads start from).
HeadConfig defaultHeadConfig();
// `config` with every imperfection of a real head set to none: the low half's
// misalignment, slot errors, LED warm-up, backlash, homing repeatability,
// gamma and rolling shutter (docs/virtual-head.md).
HeadConfig idealOf(HeadConfig config);

// Reads a head file; every fault throws ConfigError naming the file, line and key.
HeadConfig loadHeadConfig(const std::filesystem::path& file);
// Reads the head from a table: the root of head.toml or a [sim] section of a board profile.
HeadConfig parseHeadConfig(const toml::table& table, const std::string& file,
                           const std::string& path = "");

// Throws std::invalid_argument for impossible combinations (e.g. main not first).
void validate(const HeadConfig& config);

// The cameras at another resolution with the same fields of view.
HeadConfig withResolution(HeadConfig config, int width, int height);

}  // namespace cylscan::sim
