// SPDX-License-Identifier: Apache-2.0
// cylscan scan: one acquisition on a board profile (docs/formats.md, command
// line): the firmware's acquisition loop (firmware/acquisition.hpp) drives
// the stage, the trigger and the cameras through the drivers, folds every
// frame into the phase engine as it arrives, and writes the capture bundle
// (executed angles); with
// --calib and --cloud it also reconstructs on the fly (main's cloud). With a
// ring profile ([scan] plan = "ring", e.g. board/sim360) every camera of the
// profile is scanned and the bundle holds each camera's own sets.
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/board.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/bundle_phase.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/peak_memory.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_output.hpp"
#include "firmware/scan_plan.hpp"
#include "firmware/shipped_boards.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/images.hpp"
#include "formats/input_error.hpp"
#include "formats/point_cloud.hpp"
#include "tools/cloud_output.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct ScanRequest {
  std::string board;  // empty: the shipped board/sim
  std::string out;
  std::string calib;
  std::string cloud;
  std::string depth;
  std::string scene;
  std::string mode;  // empty: the profile's
  std::string phase;
  std::vector<std::string> cameras;
  int frames = 0;  // 0: the profile's
  bool no_verify = false;
  bool json = false;
};

void checkRequest(const ScanRequest& r) {
  if (r.out.empty() && r.cloud.empty())
    throw std::invalid_argument("scan: give --out BUNDLE, --cloud cloud.ply, or both");
  if (!r.cloud.empty() && r.calib.empty())
    throw std::invalid_argument("scan: --cloud needs --calib CALIB");
  if (!r.calib.empty() && r.cloud.empty())
    throw std::invalid_argument("scan: --calib is for --cloud cloud.ply");
  if (!r.depth.empty() && r.cloud.empty())
    throw std::invalid_argument("scan: --depth comes with --cloud");
  if (!drivers::virtualHeadBuilt()) {
    const std::string why = std::string(drivers::kNoVirtualHead);
    if (r.board.empty()) throw std::invalid_argument("scan: give --board DIR: " + why);
    if (!r.scene.empty())
      throw std::invalid_argument("scan: --scene is for the virtual head, and " + why);
  }
}

firmware::ScanOptions optionsFor(const ScanRequest& request, const drivers::BoardProfile& profile) {
  firmware::ScanOptions options = firmware::scanOptionsFrom(profile);
  if (request.frames > 0) options.frames_high = options.frames_low = request.frames;
  if (request.mode == "stop") options.mode = firmware::ScanMode::StopAndGo;
  if (request.mode == "continuous") options.mode = firmware::ScanMode::Continuous;
  if (request.no_verify) options.verify_steps = false;
  // Default: the profile's (main alone for a sets plan, every camera for a ring).
  if (!request.cameras.empty()) options.cameras = request.cameras;
  if (options.cameras.empty() || options.cameras.front() != "main")
    throw std::invalid_argument("scan: the first camera must be 'main'");
  for (const auto& name : options.cameras)
    (void)profile.camera(name);  // invalid_argument naming an unknown camera
  return options;
}

json jitterJson(const drivers::JitterStats::Snapshot& s) {
  auto us = [](std::chrono::nanoseconds t) { return static_cast<double>(t.count()) / 1e3; };
  return {{"count", s.count}, {"p50_us", us(s.p50)}, {"p99_us", us(s.p99)}, {"max_us", us(s.max)}};
}

void printRing(const firmware::RingLayout& ring) {
  std::cout << "  ring plan: " << ring.frames << " frames a sweep, step " << std::setprecision(4)
            << ring.step_deg << " deg (" << ring.step_steps << " steps), sweep 1 from "
            << std::setprecision(3) << ring.start_deg << " deg, sweep 2 from "
            << ring.sweep2_start_deg << " deg; phase noise vs ideal N-step: high "
            << ring.noise_gain_high << ", low " << ring.noise_gain_low << "\n";
  for (const firmware::RingCamera& c : ring.cameras) {
    std::cout << "    " << c.camera << ": sweep 1 = " << toString(c.first_sweep_set)
              << " set; margins " << std::setprecision(2) << c.window_margin_deg
              << " deg to an equivalent-period wrap, " << c.half_margin_deg
              << " deg to a half boundary\n";
  }
}

void runScan(const ScanRequest& request) {
  firmware::Stopwatch total;
  checkRequest(request);
  std::optional<algo::QuasiCalibration> calib;
  if (!request.calib.empty()) calib = readQuasiCalibration(request.calib);
  drivers::Board board = drivers::Board::open(
      request.board.empty() ? firmware::shippedBoard("sim") : fs::path(request.board),
      request.scene.empty() ? std::nullopt : std::optional<fs::path>(request.scene));
  const drivers::BoardProfile& profile = board.profile();
  const firmware::ScanOptions options = optionsFor(request, profile);
  // A ring is the head's layout, planned for every camera of the profile even
  // when fewer are scanned: each camera's quasi-calibration holds for the
  // phase origin (its sets' first angles) of that layout only.
  firmware::ScanOptions layout = options;
  if (options.plan == firmware::PlanKind::Ring)
    layout.cameras = firmware::scanOptionsFrom(profile).cameras;
  const firmware::ScanPlan plan = firmware::planScan(layout, profile.stage);
  const drivers::CameraProfile& main = profile.camera("main");
  if (calib && main.config.width > 0) {
    try {
      calib->requireImageSize({main.config.width, main.config.height});
    } catch (const std::invalid_argument& e) {
      throw formats::InputError(request.calib,
                                std::string(e.what()) + " (board " + profile.name + ")");
    }
  }

  algo::PhaseOptions phase_options;
  phase_options.bit_depth = main.config.bit_depth;
  firmware::PhaseSink phase(plan, phase_options);
  firmware::TeeSink sinks;
  sinks.add(phase);
  std::unique_ptr<firmware::BundleSink> bundle;
  if (!request.out.empty()) {
    json extra = {{"device", "cylscan " + profile.name},
                  {"board", profile.name},
                  {"mode", firmware::toString(options.mode)},
                  {"exposure_us", main.config.exposure_us}};
    if (main.config.bit_depth > 8) extra["bit_depth"] = main.config.bit_depth;
    bundle = std::make_unique<firmware::BundleSink>(request.out, plan, options.cameras, extra);
    sinks.add(*bundle);
  }

  firmware::Acquisition acquisition(board);
  firmware::Stopwatch watch;
  const firmware::ScanReport report = acquisition.run(options, plan, sinks);
  const double acquire_ms = watch.lapMs();
  if (bundle) bundle->commit();

  json summary = {{"board", profile.name},
                  {"mode", firmware::toString(options.mode)},
                  {"cameras", options.cameras},
                  {"frames", report.frames},
                  {"retries", report.retries},
                  {"homed", report.homed},
                  {"scan_seconds", static_cast<double>(report.duration.count()) / 1e9},
                  {"set_seconds",
                   {{"high", static_cast<double>(report.set_duration[0].count()) / 1e9},
                    {"low", static_cast<double>(report.set_duration[1].count()) / 1e9}}},
                  {"realtime", report.realtime},
                  {"warnings", report.warnings},
                  {"step_jitter", jitterJson(report.step_jitter)},
                  {"step_reramps", report.step_reramps},
                  {"trigger_jitter", jitterJson(report.trigger_jitter)},
                  {"stage_deg", {{"high", report.high_deg}, {"low", report.low_deg}}}};
  summary["plan"] = firmware::toString(options.plan);
  if (plan.ring) summary["ring"] = firmware::ringLayoutJson(*plan.ring);
  summary["scan_seconds_split"] = firmware::timeSplitSeconds(report.split);
  summary["first_set"] = std::string(toString(report.first_set));
  if (report.step_check) {
    summary["step_check"] = {{"expected_edge", report.step_check->expected_edge},
                             {"found_edge", report.step_check->found_edge},
                             {"lost_steps", report.step_check->lostSteps()},
                             {"passed", report.step_check->passed}};
  }
  if (!request.out.empty()) summary["out"] = request.out;
  if (calib) {
    // The daemon's output step, main's cloud and depth map only.
    firmware::ScanOutputOptions output;
    output.phase =
        request.phase.empty() ? calib->info().phase_source : parsePhaseSource(request.phase);
    output.cloud = request.cloud;
    output.depth = request.depth;
    output.previews = false;
    firmware::ScanCalibrations calibrations;
    calibrations.main = std::move(calib);
    const firmware::ScanResult result = firmware::writeScanOutput(phase, calibrations, output, {});
    summary["cloud"] = request.cloud;
    summary["points"] = result.figures.points.value_or(0);
    summary["phase"] = toString(result.figures.phase);
    summary["phase_valid_fraction"] = result.figures.phase_valid_fraction;
    summary["order_residual"] = firmware::orderResidualJson(result.figures.order_residual);
  }
  summary["timings_ms"] = {{"acquire", acquire_ms}, {"total", total.elapsedMs()}};
  summary["peak_resident_bytes"] = firmware::peakResidentBytes();
  if (request.json) {
    std::cout << summary.dump() << "\n";
    return;
  }
  std::cout << std::fixed << std::setprecision(3) << "scan (" << profile.name << ", "
            << firmware::toString(options.mode) << "): " << report.frames << " frames in "
            << summary["scan_seconds"].get<double>() << " s of board time (sets "
            << summary["set_seconds"]["high"].get<double>() << " + "
            << summary["set_seconds"]["low"].get<double>() << " s)";
  if (report.retries) std::cout << ", " << report.retries << " retried";
  const auto& split = summary["scan_seconds_split"];
  std::cout << "\n  homing " << split["homing"].get<double>() << " s, travel "
            << split["travel"].get<double>() << " s, sets " << split["sets"].get<double>()
            << " s, settling " << split["settling"].get<double>() << " s, step check "
            << split["step_check"].get<double>() << " s";
  std::cout << "\n  step lateness p50/p99/max " << report.step_jitter.p50.count() / 1e3 << "/"
            << report.step_jitter.p99.count() / 1e3 << "/" << report.step_jitter.max.count() / 1e3
            << " us" << (report.realtime ? " (SCHED_FIFO)" : " (normal priority)") << "\n";
  if (plan.ring) printRing(*plan.ring);
  for (const auto& w : report.warnings)
    std::cout << "  warning: " << w << "\n";
  if (!request.out.empty()) std::cout << "  bundle -> " << request.out << "\n";
  if (summary.contains("cloud"))
    std::cout << "  cloud: " << summary["points"].get<std::size_t>() << " points -> "
              << request.cloud << "\n";
}

}  // namespace

void addScanCommand(CLI::App& app) {
  auto request = std::make_shared<ScanRequest>();
  CLI::App* cmd = app.add_subcommand("scan", "one acquisition on a board (default board/sim)");
  cmd->add_option("--board", request->board,
                  "board profile folder (default: the shipped board/sim, the virtual head)");
  cmd->add_option("--out", request->out, "capture bundle to write");
  cmd->add_option("--calib", request->calib, "quasi-calibration for --cloud");
  cmd->add_option("--cloud", request->cloud, "point cloud to write (needs --calib)");
  cmd->add_option("--depth", request->depth, "depth map to write (with --cloud)");
  cmd->add_option("--scene", request->scene, "virtual head only: the scene file to scan");
  cmd->add_option("--mode", request->mode, "stop (stop and go) or continuous (the profile's)")
      ->check(CLI::IsMember({"stop", "continuous"}));
  cmd->add_option("--frames", request->frames, "frames per set (default: the profile's)")
      ->check(CLI::Range(3, 1000));
  cmd->add_option("--camera", request->cameras,
                  "camera to capture (repeatable; main first; default: main, or every camera "
                  "of a ring profile)");
  cmd->add_option("--phase", request->phase, "absolute phase for --cloud: fused or high")
      ->check(CLI::IsMember({"high", "fused"}));
  cmd->add_flag("--no-verify", request->no_verify,
                "no seek of home after a scan that passed no home edge");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runScan(*request); });
}

}  // namespace cylscan::tools
