// SPDX-License-Identifier: Apache-2.0
// The record of the last update, DATA/update/last.json (docs/http-api.md,
// "System update"): what was installed into which slot, and how it ended,
// settled at the next start by the slot the head came up on.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace cylscan::firmware {

struct UpdateRecord {
  std::string version;
  std::string target_slot;  // the bootname installed into ("a", "b"); "" unknown
  // "installing" | "installed" (waiting for the reboot) | "failed" |
  // "booted" | "rolled back"
  std::string result;
  std::string message;
  std::string time;  // UTC, ISO 8601, when the result was recorded
  // The kernel's boot id when it was installed: a start in the same boot
  // (the daemon restarted, no reboot yet) leaves an "installed" record alone.
  std::string boot_id;

  nlohmann::json toJson() const;
};

// The record in `file`; nullopt when there is none or it does not read as
// one (a damaged record is not worth refusing updates for).
std::optional<UpdateRecord> readUpdateRecord(const std::filesystem::path& file);
// Written atomically (temporary, fsync, rename); std::system_error.
void writeUpdateRecord(const std::filesystem::path& file, const UpdateRecord& record);

// The record as it stands at a start in boot `boot_id` from `booted_slot`: an
// "installed" record becomes "booted" when the head came up on its target,
// "rolled back" otherwise; an "installing" one (the daemon stopped during
// the install) becomes "failed". Any other record is returned unchanged.
// An "installed" record of the same boot is left as it is (no reboot yet).
UpdateRecord settleUpdateRecord(UpdateRecord record, const std::string& booted_slot,
                                const std::string& boot_id, const std::string& now);

// "2026-12-06T07:32:36Z".
std::string utcTimestamp();

}  // namespace cylscan::firmware
