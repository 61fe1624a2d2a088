// SPDX-License-Identifier: Apache-2.0
// A/B updates of the head (PUT /api/v1/system/update): the bundle streamed
// to DATA/update/bundle.raucb.part, checked by the updater, installed into
// the other slot on a thread of its own, the result kept in
// DATA/update/last.json and a reboot asked for through
// DATA/update/reboot-request (the image's path unit reboots; the daemon holds
// no privilege to). States: idle → receiving → installing → idle.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "firmware/daemon/head_service.hpp"
#include "firmware/daemon/update_installer.hpp"
#include "firmware/daemon/update_record.hpp"

namespace cylscan::firmware {

struct UpdateOptions {
  std::filesystem::path data_dir;
  std::uint64_t max_bundle_bytes = 1ull << 30;
  // Kept free on the data file system beyond the bundle: the daemon must
  // still commit scans' records, last.json and cameras.json, and the journal
  // write its logs, while a bundle that fits to the byte fills the disk.
  std::uint64_t reserve_bytes = 32ull << 20;
  bool reboot = true;  // write the reboot request after a successful install
  std::filesystem::path command_line = "/proc/cmdline";  // the booted slot without RAUC
  std::filesystem::path boot_id = "/proc/sys/kernel/random/boot_id";
};

class UpdateService {
 public:
  using Publish = std::function<void(const std::string& name, const nlohmann::json& data)>;
  // Throws the ServiceError (409, 503) that keeps an update from starting
  // now: a scan or a capture runs, the daemon stops.
  using RefuseIfBusy = std::function<void()>;

  // `installer` null: no updater (every update is 503). Settles last.json
  // against the booted slot and clears what a past update left behind.
  UpdateService(UpdateOptions options, std::shared_ptr<UpdateInstaller> installer, Publish publish,
                RefuseIfBusy refuse_if_busy);
  ~UpdateService();  // stop()
  UpdateService(const UpdateService&) = delete;
  UpdateService& operator=(const UpdateService&) = delete;

  // Stops waiting for an install (RAUC goes on by itself) and joins it.
  void stop() noexcept;

  // HeadService::beginUpdate.
  std::unique_ptr<UpdateUpload> begin(std::uint64_t bytes);
  // Whether an update is being received or installed (a scan must wait).
  bool busy() const { return state_.load() != State::Idle; }
  // "an update is being received" / "... installed".
  std::string busyMessage() const;
  // GET /api/v1/system's "slots", "updates" and "update".
  nlohmann::json report() const;
  // Tests: waits until no update is received or installed.
  bool waitUntilIdle(std::chrono::milliseconds timeout) const;

  std::filesystem::path dir() const { return options_.data_dir / "update"; }

 private:
  enum class State { Idle, Receiving, Installing };
  class Upload;

  // The upload's end (called by Upload).
  void abandon(const std::string& why);  // removes the files; records failed when `why` is set
  nlohmann::json startInstall(const std::filesystem::path& bundle);
  void install(const std::filesystem::path& bundle, const UpdateRecord& record,
               std::stop_token stop);
  void record(const UpdateRecord& record);
  void requestReboot(const UpdateRecord& record);
  void received(std::uint64_t received, std::uint64_t expected);
  void setIdle();
  nlohmann::json updateJson() const;
  void publishState() noexcept;
  void settleAtStart();
  std::string bootedSlot() const;

  UpdateOptions options_;
  std::shared_ptr<UpdateInstaller> installer_;
  Publish publish_;
  RefuseIfBusy refuse_if_busy_;

  std::atomic<State> state_{State::Idle};
  mutable std::mutex mutex_;
  mutable std::condition_variable idle_cv_;
  int progress_ = 0;  // mutex_
  std::string progress_message_;
  std::optional<UpdateRecord> last_;
  std::mutex thread_mutex_;  // install_thread_ between the HTTP thread and stop()
  std::jthread install_thread_;
};

}  // namespace cylscan::firmware
