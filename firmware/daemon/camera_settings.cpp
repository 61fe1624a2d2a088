// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/camera_settings.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "formats/atomic_file.hpp"

namespace cylscan::firmware {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::optional<double> control(const json& camera, const char* key, const std::string& where) {
  if (!camera.contains(key)) return std::nullopt;
  const json& v = camera.at(key);
  if (!v.is_number() || !std::isfinite(v.get<double>()) || !(v.get<double>() > 0))
    throw std::runtime_error(where + "." + key + ": must be a positive number");
  return v.get<double>();
}

}  // namespace

CameraControlSettings readCameraSettings(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    if (!fs::exists(file)) return {};
    throw std::runtime_error(file.string() + ": cannot be read");
  }
  std::ostringstream text;
  text << in.rdbuf();
  json doc;
  try {
    doc = json::parse(text.str());
  } catch (const json::exception& e) {
    throw std::runtime_error(file.string() + ": not valid JSON: " + e.what());
  }
  if (!doc.is_object()) throw std::runtime_error(file.string() + ": must be a JSON object");
  CameraControlSettings out;
  for (const auto& [name, camera] : doc.items()) {
    const std::string where = file.string() + ": " + name;
    if (!camera.is_object()) throw std::runtime_error(where + ": must be an object");
    CameraControlSetting setting;
    setting.exposure_us = control(camera, "exposure_us", where);
    setting.gain = control(camera, "gain", where);
    out.emplace(name, setting);
  }
  return out;
}

void writeCameraSettings(const fs::path& file, const CameraControlSettings& settings) {
  json doc = json::object();
  for (const auto& [name, setting] : settings) {
    json camera = json::object();
    if (setting.exposure_us) camera["exposure_us"] = *setting.exposure_us;
    if (setting.gain) camera["gain"] = *setting.gain;
    doc[name] = std::move(camera);
  }
  formats::writeFileAtomically(file, doc.dump(2) + "\n");
}

drivers::CameraConfig withSetting(drivers::CameraConfig config,
                                  const CameraControlSetting& setting) {
  if (setting.exposure_us) config.exposure_us = *setting.exposure_us;
  if (setting.gain) config.gain = *setting.gain;
  return config;
}

}  // namespace cylscan::firmware
