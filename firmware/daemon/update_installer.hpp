// SPDX-License-Identifier: Apache-2.0
// What the daemon needs of the system's A/B updater: check a bundle, install
// it into the slot not booted, and say which slots there are. RAUC over
// D-Bus is the implementation on an image (firmware/daemon/rauc_installer.hpp);
// tests give a fake. Every call may block on the updater, so none is made
// under a lock an HTTP thread or the scan worker waits for.
#pragma once

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <stop_token>
#include <string>
#include <vector>

namespace cylscan::firmware {

// Why the updater refused or failed. Unavailable: there is no updater to ask
// (no system bus, RAUC not installed: a PC); Rejected: the bundle itself is
// unusable (signature, format, unreadable); Failed: the installation ran and
// failed, with the updater's message.
class UpdateError : public std::runtime_error {
 public:
  enum class Kind { Unavailable, Rejected, Failed };
  UpdateError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

// A bundle's manifest, as the updater read it after checking its signature.
struct BundleInfo {
  std::string compatible;
  std::string version;
};

// One slot of the updater (RAUC's GetSlotStatus).
struct SlotStatus {
  std::string name;         // "rootfs.0"
  std::string bootname;     // "a"
  bool booted = false;      // the running system's slot
  std::string boot_status;  // "good" | "bad" | "" unknown
  std::string version;      // the bundle version installed there; "" unknown
  std::string installed;    // when it was installed (the updater's timestamp); "" unknown
};

// An installation's progress: percent 0..100 and what the updater is doing.
using InstallProgress = std::function<void(int percent, const std::string& message)>;

class UpdateInstaller {
 public:
  virtual ~UpdateInstaller() = default;
  // The bundle's compatible and version; the updater verifies its signature
  // first. UpdateError Rejected (bad bundle) or Unavailable.
  virtual BundleInfo info(const std::filesystem::path& bundle) = 0;
  // Installs the bundle into the other slot and returns once the updater
  // says it completed, calling `progress` as it goes. Blocks its caller: the
  // service runs it on a thread of its own. UpdateError Failed with the
  // updater's last error; returns early (Failed, "cancelled") when `stop`
  // is requested, leaving the updater to finish on its own.
  virtual void install(const std::filesystem::path& bundle, const InstallProgress& progress,
                       std::stop_token stop) = 0;
  // The slots; UpdateError Unavailable without an updater.
  virtual std::vector<SlotStatus> slots() = 0;
  // The system's compatible (a bundle must carry the same).
  virtual std::string compatible() = 0;
  // The bootname of the booted slot ("a", "b").
  virtual std::string bootSlot() = 0;
};

}  // namespace cylscan::firmware
