// SPDX-License-Identifier: Apache-2.0
// cylscan simulate: renders a dataset on the virtual head (docs/formats.md,
// simulated dataset). The head is a board, and every frame comes through the
// firmware's acquisition loop (tools/sim_capture.hpp); the datasets
// themselves are in tools/sim_dataset.hpp (one direction) and
// tools/sim_ring.hpp (a 360° head).
#include <memory>
#include <stdexcept>

#include "firmware/scan_plan.hpp"
#include "tools/commands.hpp"
#include "tools/sim_capture.hpp"
#include "tools/sim_dataset.hpp"
#include "tools/sim_request.hpp"
#include "tools/sim_ring.hpp"

namespace cylscan::tools {
namespace {

void runSimulate(SimulateRequest request) {
  const auto started = SimClock::now();
  if (request.quick) {
    if (request.width == 0) request.width = 320;
    if (request.height == 0) request.height = 256;
  }
  if ((request.width == 0) != (request.height == 0)) {
    throw std::invalid_argument("simulate: give both --width and --height");
  }
  const drivers::BoardProfile profile = simulationProfile(request);
  const firmware::ScanOptions options = simulationOptions(request, profile);
  if (request.write_calibration_scenes) {
    if (options.plan == firmware::PlanKind::Ring || !request.camera.empty() || request.turntable) {
      throw std::invalid_argument(profile.file.string() +
                                  ": --write-calibration-scenes is for a one-direction head "
                                  "(cameras main and aux), without --camera or --turntable");
    }
    writeCalibrationScenes(request, profile);
    return;
  }
  if (options.plan == firmware::PlanKind::Ring) {
    writeRingDataset(request, started);
    return;
  }
  if (!request.camera.empty() || request.turntable) {
    throw std::invalid_argument(profile.file.string() +
                                ": --camera and --turntable are for a 360° head's board "
                                "([scan] plan = \"ring\", e.g. board/sim360)");
  }
  const firmware::ScanPlan plan = firmware::planScan(options, profile.stage);
  checkPlanAgainstHead(plan, profile);
  writeDataset(request, profile, options, plan, nlohmann::json::object(), nlohmann::json::object(),
               started);
}

}  // namespace

void addSimulateCommand(CLI::App& app) {
  auto request = std::make_shared<SimulateRequest>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "render a dataset on the virtual head (docs/formats.md, simulated dataset)");
  cmd->add_option("--out", request->out, "output directory")->required();
  cmd->add_option("--board", request->board,
                  "the board whose virtual head renders it (default: the shipped board/sim); a "
                  "360° head's board (e.g. board/sim360) with --camera, --turntable or neither "
                  "(a ring scan of its default scene)");
  cmd->add_option("--head", request->head, "virtual head file in place of the board's [sim] head");
  cmd->add_option("--width", request->width, "image width (intrinsics scaled, same field of view)")
      ->check(CLI::Range(64, 4096));
  cmd->add_option("--height", request->height, "image height")->check(CLI::Range(64, 4096));
  CLI::Option* frames =
      cmd->add_option("--frames", request->frames, "frames per fringe set (default: the board's)")
          ->check(CLI::Range(3, 200));
  cmd->add_option("--noise", request->noise, "scale on the noise model (0: noiseless)")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--seed", request->seed, "noise seed (same seed, same bytes)");
  cmd->add_option("--scene", request->scenes, "extra test scene file (repeatable)");
  cmd->add_option("--poses", request->poses, "calibration plane poses")->check(CLI::Range(1, 100));
  cmd->add_option("--boards", request->boards, "checkerboard poses")->check(CLI::Range(1, 99));
  cmd->add_option("--bit-depth", request->bit_depth, "camera bit depth (8, 10, 12 or 16)")
      ->check(CLI::IsMember({8, 10, 12, 16}));
  cmd->add_option("--sphere-poses", request->sphere_poses,
                  "study: poses of the 50 mm sphere (scenes sphere_poseNN, main+aux)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--plane-poses", request->plane_poses,
                  "study: test plane poses (scenes plane_poseNN, main+aux)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--repeats", request->repeats,
                  "study: repeated scans of two fixed sphere and plane poses "
                  "(sphere_repeatP_rNN, plane_repeatP_rNN)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--camera", request->camera,
                  "with a 360° head's --board: the one-direction dataset of this camera");
  cmd->add_flag("--turntable", request->turntable,
                "with a 360° head's --board: the extrinsics dataset (the head on a turntable)");
  cmd->add_flag("--quick", request->quick, "320x256 unless --width/--height are given");
  cmd->add_flag("--write-calibration-scenes", request->write_calibration_scenes,
                "instead of rendering, write the calibration targets generated for the board's "
                "head to --out as scene files (--boards boardNN.toml, --poses planeNN.toml): "
                "how board/sim/scenes/calibration is made");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request, frames] {
    request->frames_given = frames->count() > 0;
    runSimulate(*request);
  });
}

}  // namespace cylscan::tools
