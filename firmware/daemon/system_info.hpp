// SPDX-License-Identifier: Apache-2.0
// What GET /api/v1/system says about the machine under the daemon: its host
// name, the root slot it booted from (an image's boot entry names it on the
// kernel command line) and the size of the data file system.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace cylscan::firmware {

// The value of `rauc.slot=` on a kernel command line ("a", "b"), or
// nothing when the system did not boot from a cylscan image.
std::optional<std::string> bootedSlot(std::string_view kernel_command_line);

// The value of KEY in os-release(5) text (`KEY=value`, the value optionally
// quoted), or nothing when the text has no such line.
std::optional<std::string> osReleaseValue(std::string_view os_release, std::string_view key);

class SystemInfo {
 public:
  // `command_line`: /proc/cmdline; `os_release`: /etc/os-release (a test's
  // files in their place).
  SystemInfo(std::string version, std::filesystem::path data_dir,
             std::filesystem::path command_line = "/proc/cmdline",
             std::filesystem::path os_release = "/etc/os-release");

  // {"version", "hostname", "slot" (null outside an image), "image": {"id",
  // "version"} (os-release's IMAGE_ID and IMAGE_VERSION; null outside an
  // image), "data": {"total_bytes", "free_bytes"} (null when it cannot be
  // read)}.
  nlohmann::json report() const;

 private:
  std::string version_;
  std::filesystem::path data_dir_;
  std::filesystem::path command_line_;
  std::filesystem::path os_release_;
};

}  // namespace cylscan::firmware
