// SPDX-License-Identifier: Apache-2.0
// A scripted A/B updater for the update tests: RAUC's answers without RAUC.
// The real D-Bus path is exercised by the image test.
#pragma once

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "firmware/daemon/update_installer.hpp"

namespace cylscan::test_support {

class FakeUpdateInstaller : public firmware::UpdateInstaller {
 public:
  using UpdateError = firmware::UpdateError;

  mutable std::mutex mutex;
  bool available = true;
  std::string system_compatible = "cylscan-sim";
  std::string bundle_compatible = "cylscan-sim";
  std::string bundle_version = "1.2.3";
  std::optional<std::string> info_error;     // Rejected with this message
  std::optional<std::string> install_error;  // Failed with this message
  std::string booted = "a";
  bool hold_install = false;                 // install() waits for release()
  std::vector<std::string> infos, installs;  // the bundles asked about
  std::vector<std::string> installed_bytes;  // the bundle's content when install began

  void release() {
    {
      std::lock_guard lock(mutex);
      hold_install = false;
    }
    cv_.notify_all();
  }
  // Waits until install() has been called `n` times.
  bool waitForInstalls(std::size_t n, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex);
    return cv_.wait_for(lock, timeout, [&] { return installs.size() >= n; });
  }

  firmware::BundleInfo info(const std::filesystem::path& bundle) override {
    std::lock_guard lock(mutex);
    check();
    infos.push_back(bundle.string());
    if (info_error) throw UpdateError(UpdateError::Kind::Rejected, *info_error);
    return {bundle_compatible, bundle_version};
  }
  void install(const std::filesystem::path& bundle, const firmware::InstallProgress& progress,
               std::stop_token stop) override {
    {
      std::unique_lock lock(mutex);
      check();
      installs.push_back(bundle.string());
      installed_bytes.push_back(readAll(bundle));
      cv_.notify_all();
    }
    progress(0, "Installing");
    progress(40, "Copying image to rootfs.1");
    {
      std::unique_lock lock(mutex);
      cv_.wait(lock, [&] { return !hold_install || stop.stop_requested(); });
      if (stop.stop_requested()) throw UpdateError(UpdateError::Kind::Failed, "cancelled");
      if (install_error) throw UpdateError(UpdateError::Kind::Failed, *install_error);
    }
    progress(100, "Installing done.");
  }
  std::vector<firmware::SlotStatus> slots() override {
    std::lock_guard lock(mutex);
    check();
    return {{"rootfs.0", "a", booted == "a", "good", "1.0.0", "2026-11-01T10:00:00Z"},
            {"rootfs.1", "b", booted == "b", "good", "", ""}};
  }
  std::string compatible() override {
    std::lock_guard lock(mutex);
    check();
    return system_compatible;
  }
  std::string bootSlot() override {
    std::lock_guard lock(mutex);
    check();
    return booted;
  }

 private:
  void check() const {
    if (!available) {
      throw UpdateError(UpdateError::Kind::Unavailable, "updates need RAUC: no system bus");
    }
  }
  static std::string readAll(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  std::condition_variable cv_;
};

}  // namespace cylscan::test_support
