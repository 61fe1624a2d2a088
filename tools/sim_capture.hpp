// SPDX-License-Identifier: Apache-2.0
// How `cylscan simulate` captures: the virtual head opened as a board and
// driven by the firmware's acquisition loop (firmware::Acquisition along a
// firmware::ScanPlan, frames into firmware::BundleSink), the path that
// `cylscan scan` and cylscand run. Nothing here moves the stage, times a
// trigger or plans an angle, so a simulated dataset is what the firmware
// captures by construction.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "drivers/board.hpp"
#include "drivers/board_profile.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/scan_plan.hpp"
#include "tools/sim_request.hpp"

namespace cylscan::tools {

// The board profile a dataset is rendered on: --board's (default: the shipped
// board/sim) with the request applied to its virtual head (--head,
// --width/--height, --noise, --bit-depth, --seed) and the cameras' settings
// made to match the head. std::invalid_argument naming the board when it has
// no virtual head or its stage or slots disagree with the head's.
drivers::BoardProfile simulationProfile(const SimulateRequest& request);
// The board's scan options ([scan], firmware::scanOptionsFrom) with --frames.
firmware::ScanOptions simulationOptions(const SimulateRequest& request,
                                        const drivers::BoardProfile& profile);

// Every virtual camera's width, height and bit depth set to its model's in
// the profile's head (the head may have been replaced or rescaled).
void matchCamerasToHead(drivers::BoardProfile& profile);

// std::invalid_argument naming the board when the plan's steps per degree or
// slot periods are not the virtual head's (the dataset would lie about its angles).
void checkPlanAgainstHead(const firmware::ScanPlan& plan, const drivers::BoardProfile& profile);

class VirtualCapture {
 public:
  // Scans take `options` (mode, settle, timeouts), each with its own cameras.
  VirtualCapture(drivers::BoardProfile profile, firmware::ScanOptions options);

  sim::VirtualHead& head() { return *board_.virtualHead(); }
  const drivers::BoardProfile& profile() const { return board_.profile(); }

  // One fringe acquisition of `scene` along `plan` by `cameras` (main first),
  // written as the capture bundle `dir` with `extra` in its capture.json.
  void scanBundle(const std::filesystem::path& dir, const sim::Scene& scene,
                  const firmware::ScanPlan& plan, const std::vector<std::string>& cameras,
                  nlohmann::json extra);
  // One exposure of each camera of `scene` with the light off (the scene's
  // ambient light only: a checkerboard under room light), in that order.
  std::vector<cv::Mat> still(const sim::Scene& scene, const std::vector<std::string>& cameras);

  int triggers() const { return triggers_; }  // fringe frames triggered so far

 private:
  firmware::ScanOptions options(const std::vector<std::string>& cameras) const;

  drivers::Board board_;
  firmware::Acquisition acquisition_;  // on board_: declared after it
  firmware::ScanOptions options_;
  int triggers_ = 0;
};

}  // namespace cylscan::tools
