// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/update_service.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <iterator>
#include <system_error>
#include <utility>

#include "firmware/daemon/log.hpp"
#include "firmware/daemon/system_info.hpp"
#include "formats/atomic_file.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kPartName = "bundle.raucb.part";
constexpr const char* kBundleName = "bundle.raucb";
constexpr const char* kRecordName = "last.json";
constexpr const char* kRebootName = "reboot-request";

std::string errnoText(int error) {
  return std::error_code(error, std::generic_category()).message();
}

std::string firstLine(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  return line;
}

void removeQuietly(const fs::path& file) {
  std::error_code ec;
  fs::remove(file, ec);
}

ServiceError refusal(const UpdateError& e) {
  if (e.kind() == UpdateError::Kind::Unavailable) return ServiceError(503, e.what());
  return ServiceError(422, std::string("RAUC refuses the bundle: ") + e.what());
}

}  // namespace

// The part file of one upload; see UpdateUpload.
class UpdateService::Upload final : public UpdateUpload {
 public:
  Upload(UpdateService& service, std::uint64_t expected)
      : service_(service), part_(service.dir() / kPartName), expected_(expected) {
    fd_ = ::open(part_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd_ < 0) {
      throw ServiceError(507, "cannot create " + part_.string() + ": " + errnoText(errno));
    }
  }
  Upload(const Upload&) = delete;
  Upload& operator=(const Upload&) = delete;

  ~Upload() override {
    if (fd_ >= 0) ::close(fd_);
    if (finished_) return;
    try {
      service_.abandon("truncated upload: the connection closed after " +
                       std::to_string(received_) + " of " + std::to_string(expected_) + " bytes");
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor reports nothing more
    }
  }

  void write(std::string_view bytes) override {
    received_ += bytes.size();
    while (!bytes.empty() && !error_) {
      const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        error_ = "cannot write " + part_.string() + ": " + errnoText(errno);
        break;
      }
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
    service_.received(received_, expected_);
  }

  json finish() override {
    finished_ = true;
    if (!error_ && received_ != expected_) {
      error_ =
          "received " + std::to_string(received_) + " of " + std::to_string(expected_) + " bytes";
    }
    if (!error_ && ::fsync(fd_) != 0)
      error_ = "cannot write " + part_.string() + ": " + errnoText(errno);
    if (::close(fd_) != 0 && !error_)
      error_ = "cannot write " + part_.string() + ": " + errnoText(errno);
    fd_ = -1;
    const fs::path bundle = service_.dir() / kBundleName;
    if (!error_ && ::rename(part_.c_str(), bundle.c_str()) != 0) {
      error_ = "cannot rename " + part_.string() + ": " + errnoText(errno);
    }
    if (!error_) {
      try {
        formats::syncDirectory(service_.dir());
      } catch (const std::system_error& e) {
        error_ = e.what();
      }
    }
    if (error_) {
      service_.abandon("");
      throw ServiceError(507, *error_);
    }
    return service_.startInstall(bundle);
  }

 private:
  UpdateService& service_;
  fs::path part_;
  std::uint64_t expected_;
  std::uint64_t received_ = 0;
  int fd_ = -1;
  bool finished_ = false;
  std::optional<std::string> error_;
};

UpdateService::UpdateService(UpdateOptions options, std::shared_ptr<UpdateInstaller> installer,
                             Publish publish, RefuseIfBusy refuse_if_busy)
    : options_(std::move(options)),
      installer_(std::move(installer)),
      publish_(std::move(publish)),
      refuse_if_busy_(std::move(refuse_if_busy)) {
  std::error_code ec;
  fs::create_directories(dir(), ec);
  if (ec) logWarn("cannot create " + dir().string() + ": " + ec.message());
  settleAtStart();
}

UpdateService::~UpdateService() {
  stop();
}

void UpdateService::stop() noexcept {
  std::lock_guard lock(thread_mutex_);
  if (install_thread_.joinable()) {
    install_thread_.request_stop();
    install_thread_.join();
  }
}

std::string UpdateService::bootedSlot() const {
  if (installer_) {
    try {
      std::string slot = installer_->bootSlot();
      if (!slot.empty()) return slot;
    } catch (const UpdateError&) {
      // The kernel command line says it too.
    }
  }
  std::ifstream in(options_.command_line);
  const std::string line{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  return firmware::bootedSlot(line).value_or("");
}

void UpdateService::settleAtStart() {
  // A bundle of an upload or install the daemon did not see to its end.
  removeQuietly(dir() / kPartName);
  removeQuietly(dir() / kBundleName);
  std::optional<UpdateRecord> last = readUpdateRecord(dir() / kRecordName);
  const std::string boot_id = firstLine(options_.boot_id);
  // A reboot request of an earlier boot has been served; one of this boot
  // (the daemon restarted before the reboot) must stay.
  if (!last || last->boot_id != boot_id) removeQuietly(dir() / kRebootName);
  if (last && (last->result == "installed" || last->result == "installing")) {
    const std::string booted = bootedSlot();
    if (!booted.empty() || last->result == "installing") {
      UpdateRecord settled = settleUpdateRecord(*last, booted, boot_id, utcTimestamp());
      if (settled.result != last->result) {
        try {
          writeUpdateRecord(dir() / kRecordName, settled);
        } catch (const std::exception& e) {
          logWarn(std::string("cannot record the update's result: ") + e.what());
        }
        logInfo("update " + settled.version + ": " + settled.result + " (" + settled.message + ")");
        last = settled;
      }
    }
  }
  std::lock_guard lock(mutex_);
  last_ = last;
}

std::unique_ptr<UpdateUpload> UpdateService::begin(std::uint64_t bytes) {
  if (bytes > options_.max_bundle_bytes) {
    throw ServiceError(413, "the bundle of " + std::to_string(bytes) +
                                " bytes is larger than update.max_bundle_bytes (" +
                                std::to_string(options_.max_bundle_bytes) + ")");
  }
  if (!installer_) throw ServiceError(503, "updates need RAUC: this daemon has no updater");
  try {
    (void)installer_->compatible();  // reachable before a byte is stored
  } catch (const UpdateError& e) {
    throw ServiceError(503, e.kind() == UpdateError::Kind::Unavailable
                                ? std::string(e.what())
                                : std::string("updates need RAUC: ") + e.what());
  }
  std::error_code ec;
  const fs::space_info space = fs::space(dir(), ec);
  if (ec)
    throw ServiceError(507,
                       "cannot read the free space of " + dir().string() + ": " + ec.message());
  if (space.available < options_.reserve_bytes ||
      bytes > space.available - options_.reserve_bytes) {
    throw ServiceError(507, "the bundle of " + std::to_string(bytes) +
                                " bytes does not fit: " + std::to_string(space.available) +
                                " bytes free on the data file "
                                "system, of which " +
                                std::to_string(options_.reserve_bytes) +
                                " stay free for the daemon's records");
  }
  State idle = State::Idle;
  if (!state_.compare_exchange_strong(idle, State::Receiving))
    throw ServiceError(409, busyMessage());
  try {
    // After the claim: a scan that starts from now on sees busy() (see ScanService).
    if (refuse_if_busy_) refuse_if_busy_();
    {
      std::lock_guard lock(mutex_);
      progress_ = 0;
      progress_message_ = "receiving the bundle";
    }
    auto upload = std::make_unique<Upload>(*this, bytes);  // nothing may throw after it
    publishState();
    return upload;
  } catch (...) {
    state_ = State::Idle;
    throw;
  }
}

void UpdateService::received(std::uint64_t received, std::uint64_t expected) {
  const int percent = expected == 0 ? 100 : static_cast<int>(received * 100 / expected);
  bool changed = false;
  {
    std::lock_guard lock(mutex_);
    // One event per 5 %, not one per block.
    changed = percent / 5 != progress_ / 5;
    progress_ = percent;
  }
  if (changed) publishState();
}

std::string UpdateService::busyMessage() const {
  return state_.load() == State::Installing ? "an update is being installed"
                                            : "an update is being received";
}

void UpdateService::abandon(const std::string& why) {
  removeQuietly(dir() / kPartName);
  removeQuietly(dir() / kBundleName);
  if (!why.empty()) {
    UpdateRecord failed;
    failed.result = "failed";
    failed.message = why;
    failed.time = utcTimestamp();
    failed.boot_id = firstLine(options_.boot_id);
    record(failed);
    logWarn("update: " + why);
  }
  setIdle();
}

json UpdateService::startInstall(const fs::path& bundle) {
  BundleInfo info;
  std::string target;
  try {
    info = installer_->info(bundle);
    const std::string compatible = installer_->compatible();
    if (info.compatible != compatible) {
      throw ServiceError(422, "bundle is for " + info.compatible + ", this head is " + compatible);
    }
    for (const SlotStatus& slot : installer_->slots()) {
      if (!slot.booted && slot.name.rfind("rootfs.", 0) == 0) target = slot.bootname;
    }
  } catch (const UpdateError& e) {
    abandon("");
    throw refusal(e);
  } catch (...) {
    abandon("");
    throw;
  }
  UpdateRecord installing;
  installing.version = info.version;
  installing.target_slot = target;
  installing.result = "installing";
  installing.time = utcTimestamp();
  installing.boot_id = firstLine(options_.boot_id);
  record(installing);
  {
    std::lock_guard lock(mutex_);
    progress_ = 0;
    progress_message_ = "installing";
  }
  state_ = State::Installing;
  publishState();
  logInfo("update: installing " + info.version + " into slot " + target);
  {
    std::lock_guard lock(thread_mutex_);
    if (install_thread_.joinable()) install_thread_.join();  // the last one, ended
    install_thread_ = std::jthread([this, bundle, installing](std::stop_token stop) {
      install(bundle, installing, std::move(stop));
    });
  }
  return {{"state", "installing"},
          {"version", info.version},
          {"target_slot", target.empty() ? json(nullptr) : json(target)}};
}

void UpdateService::install(const fs::path& bundle, const UpdateRecord& installing,
                            std::stop_token stop) {
  UpdateRecord done = installing;
  try {
    installer_->install(
        bundle,
        [this](int percent, const std::string& message) {
          {
            std::lock_guard lock(mutex_);
            progress_ = std::clamp(percent, 0, 100);
            progress_message_ = message;
          }
          publishState();
        },
        std::move(stop));
    done.result = "installed";
    done.message = options_.reboot ? "rebooting into slot " + done.target_slot
                                   : "installed; reboot to run it (update.reboot is false)";
  } catch (const std::exception& e) {
    done.result = "failed";
    done.message = e.what();
  }
  removeQuietly(bundle);
  done.time = utcTimestamp();
  record(done);
  logInfo("update " + done.version + ": " + done.result + " (" + done.message + ")");
  if (done.result == "installed" && options_.reboot) requestReboot(done);
  setIdle();
}

void UpdateService::record(const UpdateRecord& r) {
  try {
    writeUpdateRecord(dir() / kRecordName, r);
  } catch (const std::exception& e) {
    logWarn(std::string("cannot record the update's result: ") + e.what());
  }
  std::lock_guard lock(mutex_);
  last_ = r;
}

void UpdateService::requestReboot(const UpdateRecord& r) {
  const json request = {{"reason", "update"},
                        {"version", r.version},
                        {"target_slot", r.target_slot},
                        {"time", r.time}};
  try {
    formats::writeFileAtomically(dir() / kRebootName, request.dump() + "\n");
  } catch (const std::exception& e) {
    logError(std::string("cannot request the reboot: ") + e.what());
  }
}

void UpdateService::setIdle() {
  {
    std::lock_guard lock(mutex_);
    progress_ = 0;
    progress_message_.clear();
    state_ = State::Idle;
  }
  idle_cv_.notify_all();
  publishState();
}

json UpdateService::updateJson() const {
  std::lock_guard lock(mutex_);
  const State state = state_.load();
  const char* name = state == State::Idle        ? "idle"
                     : state == State::Receiving ? "receiving"
                                                 : "installing";
  json out = {{"state", name},
              {"progress", progress_},
              {"message", progress_message_},
              {"last", last_ ? last_->toJson() : json(nullptr)}};
  if (out["last"].is_object()) out["last"].erase("boot_id");
  return out;
}

void UpdateService::publishState() noexcept {
  try {
    if (publish_) publish_("update", updateJson());
  } catch (const std::exception& e) {
    logWarn(std::string("cannot publish the update's state: ") + e.what());
  }
}

json UpdateService::report() const {
  json slots = json::array();
  bool updates = false;
  if (installer_) {
    try {
      for (const SlotStatus& s : installer_->slots()) {
        if (s.bootname.empty()) continue;  // not a root slot of the image
        slots.push_back(
            {{"name", s.name},
             {"bootname", s.bootname},
             {"state", s.booted ? "booted" : "inactive"},
             {"boot_status", s.boot_status.empty() ? json(nullptr) : json(s.boot_status)},
             {"version", s.version.empty() ? json(nullptr) : json(s.version)},
             {"installed", s.installed.empty() ? json(nullptr) : json(s.installed)}});
      }
      updates = true;
    } catch (const UpdateError& e) {
      logDebug(std::string("no slots: ") + e.what());
    }
  }
  return {{"slots", slots}, {"updates", updates}, {"update", updateJson()}};
}

bool UpdateService::waitUntilIdle(std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  return idle_cv_.wait_for(lock, timeout, [&] { return state_.load() == State::Idle; });
}

}  // namespace cylscan::firmware
