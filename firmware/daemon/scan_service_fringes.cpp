// SPDX-License-Identifier: Apache-2.0
// ScanService's fringe check: a short scan of every camera at the head's
// settings, through the acquisition and the phase engine like any scan, whose
// maps say whether the exposure is right for scanning
// (firmware/fringe_check.hpp). Nothing is stored but the last pictures.
#include <string>

#include "firmware/daemon/log.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "firmware/daemon/scan_service_jobs.hpp"
#include "firmware/fringe_check.hpp"
#include "firmware/live_picture.hpp"
#include "firmware/phase_sink.hpp"

namespace cylscan::firmware {

using json = nlohmann::json;

namespace {

// Frames per set: enough for the modulation of the N-step least squares to
// be within a few per cent of a full scan's, and a third of its frames.
constexpr int kFringeCheckFrames = 8;

}  // namespace

std::future<json> ScanService::fringeCheck(const json& body) {
  const std::optional<std::string> scene = sceneOf(body);
  json options = {{"frames", kFringeCheckFrames}};
  if (scene) options["scene"] = *scene;
  Request request = validate(options);
  request.save_bundle = false;
  request.scan.cameras.clear();
  for (const auto& camera : profile_.cameras)
    request.scan.cameras.push_back(camera.name);
  request.frames_total = planScan(request.scan, profile_.stage).frames();
  auto promise = std::make_shared<std::promise<json>>();
  std::future<json> reply = promise->get_future();
  request.fringe_check = FringeCheckCapture{std::move(promise)};
  std::lock_guard lock(mutex_);
  refuseUnlessIdleLocked();
  queueCaptureLocked(std::move(request));
  return reply;
}

std::string ScanService::fringePicture(std::string_view camera) const {
  std::lock_guard lock(mutex_);
  const auto it = fringe_pictures_.find(camera);
  if (it == fringe_pictures_.end())
    throw ServiceError(
        404, "no fringe check of camera '" + std::string(camera) + "': POST /api/v1/fringe-check");
  return it->second;
}

void ScanService::runFringeCheck(Job& job) {
  const Request& request = job.request;
  std::optional<json> answer;
  std::map<std::string, std::string, std::less<>> pictures;
  std::exception_ptr failure;
  try {
    if (stopping()) throw ScanError("aborted: daemon stopping");
    if (!board_ || !acquisition_ || request.scene != board_scene_) reopenBoard(request.scene);
    const ScanPlan plan = planScan(request.scan, board_->profile().stage);
    PhaseSink phase(plan, phaseOptions());
    acquisition_->run(request.scan, plan, phase,
                      [&](const ScanProgress& p) { onProgress(job, p); });
    JpegEncoder encoder;
    json cameras = json::array();
    for (const std::string& camera : request.scan.cameras) {
      const FringeQuality q = measureFringes(phase.finalize(camera), phase.options(camera));
      pictures[camera] = encoder.encode(q.picture);
      cameras.push_back({{"name", camera},
                         {"exposure_us", board_->camera(camera).controls().exposure_us.value},
                         {"gain", board_->camera(camera).controls().gain.value},
                         {"modulation_median", q.modulation_median},
                         {"lit", q.lit},
                         {"usable", q.usable},
                         {"saturated", q.saturated},
                         {"peak", q.peak},
                         {"advice", toString(q.advice)}});
      logInfo("fringe check of " + camera + ": " + std::string(toString(q.advice)) + " (peak " +
              std::to_string(q.peak) + ", saturated " + std::to_string(q.saturated) + ")");
    }
    answer = json{{"frames", kFringeCheckFrames}, {"cameras", std::move(cameras)}};
  } catch (const ServiceError&) {
    failure = std::current_exception();
  } catch (const std::exception& e) {
    logError(std::string("fringe check failed: ") + e.what());
    failure = std::make_exception_ptr(
        ServiceError(503, std::string("the fringe check failed: ") + e.what()));
  }
  const auto reply = request.fringe_check->reply;
  {
    std::lock_guard lock(mutex_);
    if (answer) fringe_pictures_ = std::move(pictures);
    job_.reset();
    publishState();
    cv_.notify_all();
  }
  if (failure) {
    reply->set_exception(failure);
  } else {
    reply->set_value(std::move(*answer));
  }
}

}  // namespace cylscan::firmware
