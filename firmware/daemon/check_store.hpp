// SPDX-License-Identifier: Apache-2.0
// The head's checks against a known artifact, kept as its history: every
// finished check in DATA/checks.json (newest first, rewritten atomically
// after each), so the drift of a head in the field can be followed across
// restarts. A check is a scan of the artifact (its id is the scan's) and the
// artifact's figures measured on that scan's cloud (firmware/sphere_check.hpp).
#pragma once

#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cylscan::firmware {

struct CheckRecord {
  std::string id;                // the scan's
  std::string state = "queued";  // queued | running | done | failed
  std::string created;           // ISO 8601, UTC
  std::string artifact = "sphere";
  double radius_mm = 0;
  double tolerance_mm = 0;
  std::optional<std::string> scene;  // the virtual head's scene, when asked
  // Once done: the figures of the artifact in the scan.
  std::optional<double> measured_radius_mm, rmse_mm, probing_form_mm, probing_size_mm;
  std::size_t points = 0;
  bool pass = false;
  std::optional<std::string> error;  // failed: why
};

void to_json(nlohmann::json& j, const CheckRecord& c);
// std::runtime_error naming the field for a record that is not one.
void from_json(const nlohmann::json& j, CheckRecord& c);

class CheckStore {
 public:
  // Reads DATA/checks.json when there is one; a file that cannot be read is
  // moved aside (checks.json.broken) with a warning and the history starts
  // again, so a damaged file never stops the head.
  explicit CheckStore(const std::filesystem::path& data_dir);

  std::vector<CheckRecord> list() const;  // newest first
  // Adds a finished check at the front and writes the file (std::system_error
  // naming it when it cannot be written; the history in memory is then
  // unchanged).
  void add(const CheckRecord& record);

 private:
  std::filesystem::path file_;
  mutable std::mutex mutex_;
  std::vector<CheckRecord> checks_;
};

}  // namespace cylscan::firmware
