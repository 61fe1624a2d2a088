// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/update_record.hpp"

#include <ctime>
#include <fstream>
#include <iterator>
#include <utility>

#include "formats/atomic_file.hpp"

namespace cylscan::firmware {

nlohmann::json UpdateRecord::toJson() const {
  return {
      {"version", version},
      {"target_slot", target_slot.empty() ? nlohmann::json(nullptr) : nlohmann::json(target_slot)},
      {"result", result},
      {"message", message},
      {"time", time},
      {"boot_id", boot_id}};
}

std::optional<UpdateRecord> readUpdateRecord(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return std::nullopt;
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object()) return std::nullopt;
  const auto text_of = [&](const char* key) -> std::optional<std::string> {
    const auto it = j.find(key);
    if (it == j.end() || !it->is_string()) return std::nullopt;
    return it->get<std::string>();
  };
  UpdateRecord r;
  const auto result = text_of("result");
  if (!result) return std::nullopt;
  r.result = *result;
  r.version = text_of("version").value_or("");
  r.target_slot = text_of("target_slot").value_or("");
  r.message = text_of("message").value_or("");
  r.time = text_of("time").value_or("");
  r.boot_id = text_of("boot_id").value_or("");
  return r;
}

void writeUpdateRecord(const std::filesystem::path& file, const UpdateRecord& record) {
  formats::writeFileAtomically(file, record.toJson().dump(2) + "\n");
}

UpdateRecord settleUpdateRecord(UpdateRecord record, const std::string& booted_slot,
                                const std::string& boot_id, const std::string& now) {
  if (record.result == "installing") {
    record.result = "failed";
    record.message = "the daemon stopped before the install completed";
    record.time = now;
  } else if (record.result == "installed" && (boot_id.empty() || boot_id != record.boot_id)) {
    record.time = now;
    if (!record.target_slot.empty() && booted_slot == record.target_slot) {
      record.result = "booted";
      record.message = "running " + record.version + " from slot " + booted_slot;
    } else {
      record.result = "rolled back";
      record.message = "the new slot did not come up; the head went back to slot " + booted_slot;
    }
  }
  return record;
}

std::string utcTimestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

}  // namespace cylscan::firmware
