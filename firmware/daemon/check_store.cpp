// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/check_store.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "firmware/daemon/log.hpp"
#include "formats/atomic_file.hpp"

namespace cylscan::firmware {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

json optionalNumber(const std::optional<double>& x) {
  return x ? json(*x) : json(nullptr);
}

std::optional<double> numberOrNull(const json& j, const char* key) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  if (!j.at(key).is_number()) throw std::runtime_error(std::string(key) + ": must be a number");
  return j.at(key).get<double>();
}

}  // namespace

void to_json(json& j, const CheckRecord& c) {
  j = {{"id", c.id},
       {"state", c.state},
       {"created", c.created},
       {"artifact", c.artifact},
       {"radius_mm", c.radius_mm},
       {"tolerance_mm", c.tolerance_mm},
       {"measured_radius_mm", optionalNumber(c.measured_radius_mm)},
       {"rmse_mm", optionalNumber(c.rmse_mm)},
       {"probing_error_form_mm", optionalNumber(c.probing_form_mm)},
       {"probing_error_size_mm", optionalNumber(c.probing_size_mm)},
       {"points", c.points},
       {"pass", c.pass},
       {"scan", c.id}};
  if (c.scene) j["scene"] = *c.scene;
  if (c.error) j["error"] = *c.error;
}

void from_json(const json& j, CheckRecord& c) {
  try {
    c.id = j.at("id").get<std::string>();
    c.state = j.at("state").get<std::string>();
    c.created = j.at("created").get<std::string>();
    c.artifact = j.at("artifact").get<std::string>();
    c.radius_mm = j.at("radius_mm").get<double>();
    c.tolerance_mm = j.at("tolerance_mm").get<double>();
    c.measured_radius_mm = numberOrNull(j, "measured_radius_mm");
    c.rmse_mm = numberOrNull(j, "rmse_mm");
    c.probing_form_mm = numberOrNull(j, "probing_error_form_mm");
    c.probing_size_mm = numberOrNull(j, "probing_error_size_mm");
    c.points = j.at("points").get<std::size_t>();
    c.pass = j.at("pass").get<bool>();
    if (j.contains("scene")) c.scene = j.at("scene").get<std::string>();
    if (j.contains("error")) c.error = j.at("error").get<std::string>();
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("a check record: ") + e.what());
  }
}

CheckStore::CheckStore(const fs::path& data_dir) : file_(data_dir / "checks.json") {
  std::ifstream in(file_, std::ios::binary);
  if (!in) return;
  std::ostringstream text;
  text << in.rdbuf();
  try {
    const json doc = json::parse(text.str());
    if (!doc.is_array()) throw std::runtime_error("not a JSON array");
    for (const json& entry : doc)
      checks_.push_back(entry.get<CheckRecord>());
  } catch (const std::exception& e) {
    checks_.clear();
    const fs::path aside = file_.string() + ".broken";
    std::error_code ec;
    fs::rename(file_, aside, ec);
    logWarn(file_.string() + ": " + e.what() + "; moved to " + aside.string() +
            ", the check history starts again");
  }
}

std::vector<CheckRecord> CheckStore::list() const {
  std::lock_guard lock(mutex_);
  return checks_;
}

void CheckStore::add(const CheckRecord& record) {
  std::lock_guard lock(mutex_);
  std::vector<CheckRecord> next;
  next.reserve(checks_.size() + 1);
  next.push_back(record);
  next.insert(next.end(), checks_.begin(), checks_.end());
  formats::writeFileAtomically(file_, json(next).dump(1) + "\n");
  checks_ = std::move(next);
}

}  // namespace cylscan::firmware
