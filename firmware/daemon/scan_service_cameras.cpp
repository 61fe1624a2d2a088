// SPDX-License-Identifier: Apache-2.0
// ScanService's cameras: their exposure and gain as set through the API and
// kept in the data directory, and the live view the worker serves while no
// scan runs.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "firmware/daemon/log.hpp"
#include "firmware/daemon/scan_service.hpp"

namespace cylscan::firmware {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr const char* kCameraSettingsFile = "cameras.json";
// The live view takes at most this many pictures a second: enough to aim and
// focus by, and it leaves the processor to the rest of the head.
constexpr std::chrono::milliseconds kLivePeriod{100};
// How long one exposure of the live view may take before it is a failure.
constexpr double kLiveFrameTimeoutMs = 2000;

json rangeJson(const drivers::ControlRange& r) {
  return {{"value", r.value}, {"min", r.min}, {"max", r.max}};
}

// The value of `key` in a PATCH body, checked against the camera's range.
std::optional<double> requestedControl(const json& body, const char* key,
                                       const drivers::ControlRange& range,
                                       const std::string& camera) {
  if (!body.contains(key)) return std::nullopt;
  const json& v = body.at(key);
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    throw ServiceError(400, std::string(key) + ": must be a number");
  const double x = v.get<double>();
  if (x < range.min || x > range.max) {
    std::ostringstream text;
    text << key << ": " << x << " is out of camera " << camera << "'s range [" << range.min << ", "
         << range.max << "]";
    throw ServiceError(400, text.str());
  }
  return x;
}

}  // namespace

void ScanService::loadCameraSettings() {
  CameraControlSettings settings;
  try {
    settings = readCameraSettings(options_.data_dir / kCameraSettingsFile);
  } catch (const std::exception& e) {
    logWarn(std::string(e.what()) + "; the board profile's exposure and gain are used");
  }
  std::erase_if(settings, [&](const auto& entry) {
    const auto names = board_->cameraNames();
    const bool known = std::find(names.begin(), names.end(), entry.first) != names.end();
    if (!known) logWarn("camera settings: the board has no camera " + entry.first + "; ignored");
    return !known;
  });
  {
    std::lock_guard lock(mutex_);
    camera_settings_ = settings;
  }
  applyCameraSettings(settings);
}

void ScanService::applyCameraSettings(const CameraControlSettings& settings) {
  std::map<std::string, drivers::CameraControls, std::less<>> controls;
  for (const auto& camera : profile_.cameras) {
    drivers::Camera& device = board_->camera(camera.name);
    const auto it = settings.find(camera.name);
    if (it != settings.end()) {
      try {
        device.configure(withSetting(camera.config, it->second));
      } catch (const std::exception& e) {
        // A setting the camera no longer takes (another sensor on the same
        // board) must not stop the head: the profile's values stand.
        logWarn("camera " + camera.name + ": its exposure and gain are not applied: " + e.what());
        device.configure(camera.config);
      }
    }
    controls[camera.name] = device.controls();
  }
  std::lock_guard lock(mutex_);
  camera_controls_ = std::move(controls);
  cv_.notify_all();
}

json ScanService::cameraJsonLocked(const drivers::CameraProfile& camera) const {
  json out = {{"name", camera.name},
              {"width", camera.config.width},
              {"height", camera.config.height},
              {"bit_depth", camera.config.bit_depth},
              {"calibrated", calibration_info_.count(camera.name) > 0}};
  drivers::CameraControls controls;
  if (const auto it = camera_controls_.find(camera.name); it != camera_controls_.end())
    controls = it->second;
  // A value set but not yet applied by the worker is the one the next
  // picture or scan uses.
  if (const auto it = camera_settings_.find(camera.name); it != camera_settings_.end()) {
    if (it->second.exposure_us) controls.exposure_us.value = *it->second.exposure_us;
    if (it->second.gain) controls.gain.value = *it->second.gain;
  }
  out["controls"] = {{"exposure_us", rangeJson(controls.exposure_us)},
                     {"gain", rangeJson(controls.gain)}};
  return out;
}

json ScanService::cameras() const {
  std::lock_guard lock(mutex_);
  json out = json::array();
  for (const auto& camera : profile_.cameras)
    out.push_back(cameraJsonLocked(camera));
  return out;
}

json ScanService::setCameraControls(std::string_view name, const json& body) {
  const auto names = profile_.cameras;
  const auto it =
      std::find_if(names.begin(), names.end(), [&](const auto& c) { return c.name == name; });
  if (it == names.end()) throw ServiceError(404, "no such camera: " + std::string(name));
  if (!body.is_object()) throw ServiceError(400, "the body must be a JSON object");
  for (const auto& [key, value] : body.items()) {
    if (key != "exposure_us" && key != "gain")
      throw ServiceError(400, key + ": not a camera control (exposure_us, gain)");
  }
  // One writer of the file at a time, and the file written before the
  // worker may use the value: what a scan used is what a restart finds.
  std::lock_guard file_lock(settings_file_mutex_);
  CameraControlSettings settings;
  {
    std::lock_guard lock(mutex_);
    if (stopping_) throw ServiceError(503, "the daemon is stopping");
    if (job_) throw ServiceError(409, busyMessageLocked());
    const auto controls = camera_controls_.find(name);
    if (controls == camera_controls_.end())
      throw ServiceError(503, "camera " + std::string(name) + " is not configured yet");
    CameraControlSetting& setting = camera_settings_[std::string(name)];
    CameraControlSetting updated = setting;
    if (auto x = requestedControl(body, "exposure_us", controls->second.exposure_us, it->name))
      updated.exposure_us = x;
    if (auto g = requestedControl(body, "gain", controls->second.gain, it->name)) updated.gain = g;
    setting = updated;
    settings = camera_settings_;
  }
  try {
    writeCameraSettings(options_.data_dir / kCameraSettingsFile, settings);
  } catch (const std::exception& e) {
    logError(std::string("camera settings not kept: ") + e.what());
    throw ServiceError(507, std::string("the camera settings cannot be kept: ") + e.what());
  }
  std::lock_guard lock(mutex_);
  camera_settings_changed_ = true;
  cv_.notify_all();
  logInfo("camera " + it->name + ": controls set to " + body.dump());
  return cameraJsonLocked(*it);
}

std::unique_ptr<LiveStream> ScanService::openLiveView(const LiveViewRequest& request) {
  const auto& cameras = profile_.cameras;
  const bool known = std::any_of(cameras.begin(), cameras.end(),
                                 [&](const auto& c) { return c.name == request.camera; });
  if (!known) throw ServiceError(404, "no such camera: " + request.camera);
  std::unique_ptr<LiveStream> stream;
  {
    std::lock_guard lock(mutex_);
    if (stopping_) throw ServiceError(503, "the daemon is stopping");
    if (job_) throw ServiceError(409, busyMessageLocked() + "; the live view resumes after it");
    stream = live_.subscribe(request);
  }
  cv_.notify_all();
  return stream;
}

void ScanService::serveLiveView() {
  const auto wait = last_live_capture_ + kLivePeriod - std::chrono::steady_clock::now();
  if (wait > std::chrono::steady_clock::duration::zero()) {
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, wait, [&] { return stopping_ || job_ || camera_settings_changed_; }))
      return;  // the worker sees to it first
  }
  std::vector<std::string> all;
  for (const auto& camera : profile_.cameras)
    all.push_back(camera.name);
  StillOptions still;
  std::uint64_t capture = 0;
  {
    // Begun under mutex_: a stream opened after a PATCH is answered with a
    // picture taken with the patched values.
    std::lock_guard lock(mutex_);
    if (stopping_ || job_ || camera_settings_changed_) return;
    still.cameras = live_.watched(all);
    if (still.cameras.empty()) return;
    capture = live_.beginCapture();
  }
  still.light = true;
  still.frame_timeout_ms = kLiveFrameTimeoutMs;
  last_live_capture_ = std::chrono::steady_clock::now();
  std::vector<cv::Mat> frames;
  try {
    if (!board_ || !acquisition_ || board_scene_) reopenBoard(std::nullopt);
    frames = acquisition_->still(still);
  } catch (const std::exception& e) {
    logWarn(std::string("live view: ") + e.what());
    live_.end(503, std::string("the camera failed: ") + e.what());
    return;
  }
  for (std::size_t i = 0; i < frames.size() && i < still.cameras.size(); ++i) {
    const int bit_depth = profile_.camera(still.cameras[i]).config.bit_depth;
    live_.deliver(capture, still.cameras[i], frames[i], bit_depth);
  }
}

}  // namespace cylscan::firmware
