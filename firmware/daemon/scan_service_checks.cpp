// SPDX-License-Identifier: Apache-2.0
// ScanService's checks against a known artifact: a scan of the artifact,
// queued like any other, whose cloud is measured once it is committed
// (firmware/sphere_check.hpp), and the history kept in the CheckStore.
#include <algorithm>
#include <cmath>

#include "firmware/daemon/log.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "firmware/daemon/scan_service_jobs.hpp"
#include "firmware/sphere_check.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::firmware {

using json = nlohmann::json;

namespace {

// The radius error a check allows when the request names none (README,
// "Checks"): twice the 0.05 mm to which a calibrated head measures the 50 mm
// sphere; more than that and the head has drifted from its calibration.
constexpr double kDefaultToleranceMm = 0.1;

double positiveNumber(const json& body, const char* key, double max) {
  const json& v = body.at(key);
  if (!v.is_number() || !std::isfinite(v.get<double>()) || !(v.get<double>() > 0) ||
      v.get<double>() > max)
    throw ServiceError(400, std::string(key) + ": must be a number in (0, " +
                                std::to_string(static_cast<int>(max)) + "]");
  return v.get<double>();
}

CheckRecord checkRequest(const json& body) {
  if (!body.is_object()) throw ServiceError(400, "the body must be a JSON object");
  for (const auto& [key, value] : body.items()) {
    if (key != "artifact" && key != "radius_mm" && key != "tolerance_mm" && key != "scene")
      throw ServiceError(400,
                         key + ": not a check option (artifact, radius_mm, tolerance_mm, scene)");
  }
  CheckRecord c;
  if (!body.contains("artifact") || body.at("artifact") != "sphere")
    throw ServiceError(400, "artifact: must be \"sphere\" (the only artifact checked)");
  if (!body.contains("radius_mm")) throw ServiceError(400, "radius_mm: required");
  c.radius_mm = positiveNumber(body, "radius_mm", 1000);
  c.tolerance_mm = body.contains("tolerance_mm") ? positiveNumber(body, "tolerance_mm", 100)
                                                 : kDefaultToleranceMm;
  if (body.contains("scene")) {
    if (!body.at("scene").is_string()) throw ServiceError(400, "scene: must be a string");
    c.scene = body.at("scene").get<std::string>();
  }
  return c;
}

}  // namespace

std::string ScanService::startCheck(const json& body) {
  CheckRecord check = checkRequest(body);
  json options = json::object();
  if (check.scene) options["scene"] = *check.scene;
  {
    std::lock_guard lock(mutex_);
    refuseUnlessIdleLocked();
    if (calibration_info_.count("main") == 0)
      throw ServiceError(409, "camera main has no calibration: calibrate the head before a check");
  }
  Request request = validate(options);
  request.check = std::move(check);
  requireFreeSpace(estimateBytes(request) + options_.free_space_margin_bytes);
  std::lock_guard lock(mutex_);
  refuseUnlessIdleLocked();
  return queueLocked(std::move(request));
}

json ScanService::listChecks() const {
  std::optional<CheckRecord> current;
  {
    std::lock_guard lock(mutex_);
    if (job_ && job_->check) current = *job_->check;
  }
  // Read after the job's: a check kept in the history meanwhile is listed
  // once, from the history.
  const std::vector<CheckRecord> history = checks_.list();
  json out = json::array();
  if (current && std::none_of(history.begin(), history.end(),
                              [&](const CheckRecord& c) { return c.id == current->id; }))
    out.push_back(*current);
  for (const CheckRecord& c : history)
    out.push_back(c);
  return out;
}

void ScanService::keepCheck(Job& job, const CheckRecord& check) {
  try {
    checks_.add(check);
  } catch (const std::exception& e) {
    logError(std::string("check history not kept: ") + e.what());
  }
  std::lock_guard lock(mutex_);
  job.check = check;
  events_.publish("check", check);
}

void ScanService::finishCheck(Job& job, const ScanRecord& done) {
  CheckRecord check;
  {
    std::lock_guard lock(mutex_);
    check = *job.check;
  }
  try {
    const auto cloud = store_.file(done.id, "cloud.ply");
    if (!cloud) throw std::runtime_error("the scan has no cloud (is main calibrated?)");
    SphereCheckOptions options;
    options.radius_mm = check.radius_mm;
    options.tolerance_mm = check.tolerance_mm;
    const SphereCheckResult r = checkSphere(formats::readPly(*cloud), options);
    if (!r.found) throw std::runtime_error(r.reason);
    check.state = "done";
    check.measured_radius_mm = r.measured_radius_mm;
    check.rmse_mm = r.rmse_mm;
    check.probing_form_mm = r.probing_form_mm;
    check.probing_size_mm = r.probing_size_mm;
    check.points = r.points;
    check.pass = r.pass;
    logInfo("check " + check.id + ": radius " + std::to_string(r.measured_radius_mm) + " mm (" +
            std::to_string(check.radius_mm) + " ± " + std::to_string(check.tolerance_mm) + "), " +
            (r.pass ? "pass" : "FAIL"));
  } catch (const std::exception& e) {
    check.state = "failed";
    check.pass = false;
    check.error = e.what();
    logError("check " + check.id + " failed: " + e.what());
  }
  keepCheck(job, check);
}

void ScanService::failCheck(Job& job, const std::string& error) {
  CheckRecord check;
  {
    std::lock_guard lock(mutex_);
    check = *job.check;
  }
  check.state = "failed";
  check.pass = false;
  check.error = "the scan failed: " + error;
  keepCheck(job, check);
}

}  // namespace cylscan::firmware
