// SPDX-License-Identifier: Apache-2.0
// The simulated dataset of one direction (docs/formats.md, "Simulated
// dataset"): a checkerboard set, calibration plane poses with main and aux,
// the test scenes with main (and the study scenes with both), the true stereo
// calibration and truth.json, all captured through tools/sim_capture.hpp.
#pragma once

#include <chrono>

#include <nlohmann/json.hpp>

#include "drivers/board_profile.hpp"
#include "firmware/scan_plan.hpp"
#include "tools/sim_request.hpp"

namespace cylscan::tools {

using SimClock = std::chrono::steady_clock;

// Renders the dataset on `profile`'s virtual head (cameras "main" and "aux")
// with `options` along `plan` into request.out. `bundle_extra`: extension fields of every
// capture.json; `truth_extra`: more of truth.json's "acquisition".
void writeDataset(const SimulateRequest& request, const drivers::BoardProfile& profile,
                  const firmware::ScanOptions& options, const firmware::ScanPlan& plan,
                  const nlohmann::json& bundle_extra, const nlohmann::json& truth_extra,
                  SimClock::time_point started);

// Writes the generator's calibration targets for `profile`'s head (cameras
// "main" and "aux") into request.out as scene files: request.boards
// boardNN.toml and request.poses planeNN.toml (drivers/sim/calibration_targets.hpp).
// board/sim's scenes/calibration/ is this command's output for its head.
void writeCalibrationScenes(const SimulateRequest& request, const drivers::BoardProfile& profile);

}  // namespace cylscan::tools
