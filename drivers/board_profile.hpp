// SPDX-License-Identifier: Apache-2.0
// The board profile (board/<name>/board.toml): which backends drive the head,
// where its GPIO lines are, its stage, its cameras, the acquisition defaults
// and, for the virtual head, its model. Format: board/README.md.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "drivers/camera.hpp"
#include "drivers/camera_name.hpp"
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

enum class ScanMode { StopAndGo, Continuous };

// How the stage angles of the two sets are planned. Sets: each set at its own
// start in steps of θ/N (one camera, or cameras that face the same half).
// Ring: two sweeps 180° apart in one common step for every camera of a 360°
// head; each camera takes the high or the low set from a sweep according to
// the half of the cylinder it faces (firmware/scan_plan.hpp).
enum class PlanKind { Sets, Ring };

// [scan]: defaults of the acquisition loop. The start angles are stage angles;
// the defaults put the virtual head's main field of view in the middle of the
// cylinder's high half (high set) and 180° before it on the low half (low set).
struct ScanProfile {
  int frames_high = 25;
  int frames_low = 25;
  double high_start_deg = 235.98;
  double low_start_deg = 55.98;
  ScanMode mode = ScanMode::StopAndGo;
  double frame_timeout_ms = 1000.0;
  std::optional<double> settle_ms;  // overrides [stage] settle_ms
  bool save_bundle = true;
  bool verify_steps = true;  // re-seek home after a scan: lost steps fail it
  // The projector's slot intervals: θh (high set) and θl (low set).
  double period_high_deg = 5.0;
  double period_low_deg = 5.625;
  PlanKind plan = PlanKind::Sets;
  // Ring: the common frame step (0: the planner chooses it) and the wall angle
  // where the high slots' half begins (h0: the high slots cover [h0, h0 + 180)).
  double step_deg = 0.0;
  double high_half_start_deg = 0.0;
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
  ScanProfile scan;
  std::optional<SimProfile> sim;  // set exactly when the cameras are the virtual head's

  // Throws std::invalid_argument naming the camera when there is none of that name.
  const CameraProfile& camera(std::string_view name) const;
  double settleMs() const { return scan.settle_ms.value_or(stage.settle_ms); }
};

std::string_view toString(CameraBackendKind backend);
std::string_view toString(TriggerMode trigger);
std::string_view toString(FrameStream stream);
std::string_view toString(ScanMode mode);
std::string_view toString(PlanKind plan);

// Whether this build has the virtual head (configured with CYLSCAN_WITH_SIM,
// the default). Without it, a profile whose cameras are "sim" or that has a
// [sim] table is refused with kNoVirtualHead, as is Board::open of such a profile.
bool virtualHeadBuilt();
inline constexpr std::string_view kNoVirtualHead =
    "this build has no virtual head (CYLSCAN_WITH_SIM=OFF)";

// Reads `dir`/board.toml (or the file itself when given one). Every fault
// throws sim::ConfigError (a std::invalid_argument) naming the file, the line
// and the key; unknown keys are faults. Files named in it are relative to its folder.
BoardProfile loadBoardProfile(const std::filesystem::path& dir_or_file);
// The same from a parsed table; `file` names it in messages and anchors relative paths.
BoardProfile parseBoardProfile(const toml::table& table, const std::filesystem::path& file);

}  // namespace cylscan::drivers
