// SPDX-License-Identifier: Apache-2.0
#include "tools/sim_capture.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "firmware/bundle_sink.hpp"
#include "firmware/shipped_boards.hpp"

namespace cylscan::tools {

namespace fs = std::filesystem;

drivers::BoardProfile simulationProfile(const SimulateRequest& request) {
  const fs::path board =
      request.board.empty() ? firmware::shippedBoard("sim") : fs::path(request.board);
  drivers::BoardProfile p = drivers::loadBoardProfile(board);
  const std::string where = p.file.string();
  if (!p.sim) {
    throw std::invalid_argument(
        where + ": the board has no virtual head ([sim]) for simulate to render on");
  }
  if (!request.head.empty()) {
    p.sim->head = sim::loadHeadConfig(request.head);
    p.sim->head_file = request.head;
  }
  sim::HeadConfig& head = p.sim->head;
  if (request.width > 0) head = sim::withResolution(head, request.width, request.height);
  head.noise.scale *= request.noise;
  if (request.bit_depth > 0) {
    for (auto& cam : head.cameras)
      cam.bit_depth = request.bit_depth;
  }
  p.sim->seed = request.seed;
  matchCamerasToHead(p);
  return p;
}

void matchCamerasToHead(drivers::BoardProfile& profile) {
  for (drivers::CameraProfile& c : profile.cameras) {
    const auto& models = profile.sim->head.cameras;
    const auto model = std::find_if(models.begin(), models.end(),
                                    [&](const sim::CameraParams& m) { return m.name == c.device; });
    if (model == models.end()) {
      throw std::invalid_argument(profile.file.string() + ": camera '" + c.name +
                                  "': the virtual head has no camera '" + c.device + "'");
    }
    c.config.width = model->width;
    c.config.height = model->height;
    c.config.bit_depth = model->bit_depth;
  }
}

void checkPlanAgainstHead(const firmware::ScanPlan& plan, const drivers::BoardProfile& profile) {
  const sim::HeadConfig& head = profile.sim->head;
  const std::string where = profile.file.string();
  if (std::abs(plan.steps_per_deg - head.stage.stepsPerDeg()) > 1e-9) {
    throw std::invalid_argument(where + ": [stage] has " + std::to_string(plan.steps_per_deg) +
                                " steps/deg, the virtual head " +
                                std::to_string(head.stage.stepsPerDeg()));
  }
  if (plan.period_high_deg != head.projector.theta_high_deg ||
      plan.period_low_deg != head.projector.theta_low_deg) {
    throw std::invalid_argument(where +
                                ": [scan] period_high_deg/period_low_deg differ from "
                                "the virtual head's slot periods");
  }
}

firmware::ScanOptions simulationOptions(const SimulateRequest& request,
                                        const drivers::BoardProfile& profile) {
  firmware::ScanOptions o = firmware::scanOptionsFrom(profile);
  if (request.frames_given) o.frames_high = o.frames_low = request.frames;
  return o;
}

VirtualCapture::VirtualCapture(drivers::BoardProfile profile, firmware::ScanOptions options)
    : board_(drivers::Board::open(std::move(profile))),
      acquisition_(board_),
      options_(std::move(options)) {}

firmware::ScanOptions VirtualCapture::options(const std::vector<std::string>& cameras) const {
  firmware::ScanOptions o = options_;
  o.cameras = cameras;
  return o;
}

void VirtualCapture::scanBundle(const fs::path& dir, const sim::Scene& scene,
                                const firmware::ScanPlan& plan,
                                const std::vector<std::string>& cameras, nlohmann::json extra) {
  head().setScene(scene);
  firmware::BundleSink bundle(dir, plan, cameras, std::move(extra));
  const firmware::ScanReport report = acquisition_.run(options(cameras), plan, bundle);
  bundle.commit();
  triggers_ += report.frames;
}

std::vector<cv::Mat> VirtualCapture::still(const sim::Scene& scene,
                                           const std::vector<std::string>& cameras) {
  head().setScene(scene);
  const firmware::ScanOptions o = options(cameras);
  firmware::StillOptions still;
  still.cameras = cameras;
  still.light = false;
  still.frame_timeout_ms = o.frame_timeout_ms;
  still.trigger_pulse_us = o.trigger_pulse_us;
  return acquisition_.still(still);
}

}  // namespace cylscan::tools
