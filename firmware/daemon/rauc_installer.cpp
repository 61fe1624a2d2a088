// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/rauc_installer.hpp"

#ifdef CYLSCAN_WITH_SYSTEMD
#include <systemd/sd-bus.h>
#endif

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

namespace cylscan::firmware {
namespace {

constexpr std::string_view kUnavailable = "updates need RAUC";

#ifdef CYLSCAN_WITH_SYSTEMD

constexpr const char* kService = "de.pengutronix.rauc";
constexpr const char* kObject = "/";
constexpr const char* kInterface = "de.pengutronix.rauc.Installer";
// How long one method call may take: Info verifies a bundle's signature
// over its whole size, which takes a while for 1 GiB on a slow SD card.
constexpr std::uint64_t kCallTimeoutUs = 300ull * 1000 * 1000;
// RAUC's whole answer when Info refuses a bundle.
constexpr std::string_view kInfoRefused = "rauc info error";
// How often an install's wait looks at its stop token.
constexpr std::uint64_t kWaitTickUs = 200000;

std::string busErrnoText(int negative_errno) {
  return std::error_code(-negative_errno, std::generic_category()).message();
}

// The bus errors that mean "nobody to ask" rather than "RAUC said no".
bool meansUnavailable(const sd_bus_error& e) {
  if (e.name == nullptr) return false;
  const std::string_view name(e.name);
  return name == SD_BUS_ERROR_SERVICE_UNKNOWN || name == SD_BUS_ERROR_NAME_HAS_NO_OWNER ||
         name == SD_BUS_ERROR_NO_REPLY || name == SD_BUS_ERROR_DISCONNECTED ||
         name == SD_BUS_ERROR_ACCESS_DENIED || name == SD_BUS_ERROR_UNKNOWN_METHOD ||
         name == SD_BUS_ERROR_UNKNOWN_OBJECT || name == SD_BUS_ERROR_UNKNOWN_INTERFACE;
}

struct BusError {
  sd_bus_error error = SD_BUS_ERROR_NULL;
  BusError() = default;
  BusError(const BusError&) = delete;
  BusError& operator=(const BusError&) = delete;
  ~BusError() { sd_bus_error_free(&error); }
  std::string message(int r) const {
    if (error.message != nullptr) return error.message;
    return busErrnoText(r);
  }
};

// An sd-bus object released with its unref function.
template <typename T, T* (*Unref)(T*)>
struct Owned {
  T* p = nullptr;
  Owned() = default;
  Owned(const Owned&) = delete;
  Owned& operator=(const Owned&) = delete;
  ~Owned() { Unref(p); }
};
using Message = Owned<sd_bus_message, &sd_bus_message_unref>;
using Slot = Owned<sd_bus_slot, &sd_bus_slot_unref>;

// One system-bus connection, closed with the object.
class Bus {
 public:
  Bus() {
    const int r = sd_bus_open_system(&bus_);
    if (r < 0) {
      throw UpdateError(UpdateError::Kind::Unavailable,
                        std::string(kUnavailable) + ": no system bus (" + busErrnoText(r) + ")");
    }
  }
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;
  ~Bus() { sd_bus_flush_close_unref(bus_); }
  sd_bus* get() const { return bus_; }

  // A failed call: Unavailable when nobody answered, else `otherwise`.
  [[noreturn]] static void fail(const BusError& e, int r, std::string_view what,
                                UpdateError::Kind otherwise) {
    const bool absent = meansUnavailable(e.error) || e.error.name == nullptr;
    const std::string text = e.message(r);
    if (absent) {
      throw UpdateError(UpdateError::Kind::Unavailable,
                        std::string(kUnavailable) + ": " + std::string(what) + ": " + text);
    }
    throw UpdateError(otherwise, text);
  }

  std::string stringProperty(const char* name) const {
    BusError e;
    char* value = nullptr;
    const int r =
        sd_bus_get_property_string(bus_, kService, kObject, kInterface, name, &e.error, &value);
    if (r < 0) fail(e, r, name, UpdateError::Kind::Failed);
    std::string out(value != nullptr ? value : "");
    // sd-bus allocates it with malloc.
    std::free(value);  // NOLINT(cppcoreguidelines-no-malloc,cppcoreguidelines-owning-memory)
    return out;
  }

 private:
  sd_bus* bus_ = nullptr;
};

[[noreturn]] void badReply(int r, std::string_view what) {
  throw UpdateError(UpdateError::Kind::Failed, "RAUC's answer to " + std::string(what) +
                                                   " is not understood: " + busErrnoText(r));
}

// Reads a variant holding a string; skips one of any other type.
std::optional<std::string> readStringVariant(sd_bus_message* m) {
  char type = 0;
  const char* contents = nullptr;
  int r = sd_bus_message_peek_type(m, &type, &contents);
  if (r < 0) badReply(r, "GetSlotStatus");
  if (contents == nullptr || std::strcmp(contents, "s") != 0) {
    r = sd_bus_message_skip(m, "v");
    if (r < 0) badReply(r, "GetSlotStatus");
    return std::nullopt;
  }
  const char* value = nullptr;
  r = sd_bus_message_read(m, "v", "s", &value);
  if (r < 0) badReply(r, "GetSlotStatus");
  return std::string(value != nullptr ? value : "");
}

SlotStatus readSlot(sd_bus_message* m) {
  SlotStatus slot;
  const char* name = nullptr;
  int r = sd_bus_message_read(m, "s", &name);
  if (r < 0) badReply(r, "GetSlotStatus");
  slot.name = name != nullptr ? name : "";
  r = sd_bus_message_enter_container(m, 'a', "{sv}");
  if (r < 0) badReply(r, "GetSlotStatus");
  while ((r = sd_bus_message_enter_container(m, 'e', "sv")) > 0) {
    const char* key = nullptr;
    r = sd_bus_message_read(m, "s", &key);
    if (r < 0) badReply(r, "GetSlotStatus");
    const std::string_view k(key != nullptr ? key : "");
    const std::optional<std::string> value = readStringVariant(m);
    if (value) {
      if (k == "bootname") slot.bootname = *value;
      if (k == "state") slot.booted = *value == "booted";
      if (k == "boot-status") slot.boot_status = *value;
      if (k == "bundle.version") slot.version = *value;
      if (k == "installed.timestamp") slot.installed = *value;
    }
    r = sd_bus_message_exit_container(m);
    if (r < 0) badReply(r, "GetSlotStatus");
  }
  if (r < 0) badReply(r, "GetSlotStatus");
  r = sd_bus_message_exit_container(m);
  if (r < 0) badReply(r, "GetSlotStatus");
  return slot;
}

// What an install's wait learns from the bus.
struct InstallWatch {
  const InstallProgress* progress = nullptr;
  std::optional<int> completed;  // Completed's result
};

// PropertiesChanged of the Installer: a new Progress (isi) is reported.
int onPropertiesChanged(sd_bus_message* m, void* userdata, sd_bus_error* /*error*/) {
  auto* watch = static_cast<InstallWatch*>(userdata);
  const char* interface = nullptr;
  if (sd_bus_message_read(m, "s", &interface) < 0) return 0;
  if (sd_bus_message_enter_container(m, 'a', "{sv}") < 0) return 0;
  while (sd_bus_message_enter_container(m, 'e', "sv") > 0) {
    const char* key = nullptr;
    if (sd_bus_message_read(m, "s", &key) < 0) return 0;
    if (key != nullptr && std::strcmp(key, "Progress") == 0) {
      int percent = 0;
      int depth = 0;
      const char* text = nullptr;
      if (sd_bus_message_read(m, "v", "(isi)", &percent, &text, &depth) < 0) return 0;
      if (*watch->progress) (*watch->progress)(percent, text != nullptr ? text : "");
    } else if (sd_bus_message_skip(m, "v") < 0) {
      return 0;
    }
    if (sd_bus_message_exit_container(m) < 0) return 0;
  }
  return 0;
}

int onCompleted(sd_bus_message* m, void* userdata, sd_bus_error* /*error*/) {
  auto* watch = static_cast<InstallWatch*>(userdata);
  int result = -1;
  if (sd_bus_message_read(m, "i", &result) >= 0) watch->completed = result;
  return 0;
}

class RaucInstaller final : public UpdateInstaller {
 public:
  BundleInfo info(const std::filesystem::path& bundle) override {
    Bus bus;
    BusError e;
    Message reply;
    Message request;
    int r = sd_bus_message_new_method_call(bus.get(), &request.p, kService, kObject, kInterface,
                                           "Info");
    if (r >= 0) r = sd_bus_message_append(request.p, "s", bundle.c_str());
    if (r >= 0) r = sd_bus_call(bus.get(), request.p, kCallTimeoutUs, &e.error, &reply.p);
    // RAUC 1.8 answers every refusal of Info with this text alone; the
    // reason goes to its own log.
    if (r < 0 && e.error.message != nullptr && std::string_view(e.error.message) == kInfoRefused) {
      throw UpdateError(UpdateError::Kind::Rejected,
                        "not a bundle this head can trust: a bad signature, format or manifest "
                        "(RAUC's log on the head, journalctl -u rauc, says which)");
    }
    if (r < 0) Bus::fail(e, r, "Info", UpdateError::Kind::Rejected);
    const char* compatible = nullptr;
    const char* version = nullptr;
    r = sd_bus_message_read(reply.p, "ss", &compatible, &version);
    if (r < 0) badReply(r, "Info");
    return {compatible != nullptr ? compatible : "", version != nullptr ? version : ""};
  }

  void install(const std::filesystem::path& bundle, const InstallProgress& progress,
               std::stop_token stop) override {
    Bus bus;
    InstallWatch watch;
    watch.progress = &progress;
    // Subscribed before the call, so no signal of this install is missed.
    Slot changed;
    Slot completed;
    int r = sd_bus_match_signal(bus.get(), &changed.p, kService, kObject,
                                "org.freedesktop.DBus.Properties", "PropertiesChanged",
                                &onPropertiesChanged, &watch);
    if (r >= 0) {
      r = sd_bus_match_signal(bus.get(), &completed.p, kService, kObject, kInterface, "Completed",
                              &onCompleted, &watch);
    }
    if (r < 0) {
      throw UpdateError(UpdateError::Kind::Failed,
                        "cannot watch RAUC's progress: " + busErrnoText(r));
    }
    {
      BusError e;
      Message reply;
      Message request;
      r = sd_bus_message_new_method_call(bus.get(), &request.p, kService, kObject, kInterface,
                                         "InstallBundle");
      if (r >= 0) r = sd_bus_message_append(request.p, "s", bundle.c_str());
      if (r >= 0) r = sd_bus_message_append(request.p, "a{sv}", 0);
      if (r >= 0) r = sd_bus_call(bus.get(), request.p, kCallTimeoutUs, &e.error, &reply.p);
      if (r < 0) Bus::fail(e, r, "InstallBundle", UpdateError::Kind::Failed);
    }
    while (!watch.completed) {
      if (stop.stop_requested()) {
        throw UpdateError(UpdateError::Kind::Failed,
                          "cancelled: the daemon stopped before RAUC completed");
      }
      r = sd_bus_process(bus.get(), nullptr);
      if (r < 0) {
        throw UpdateError(UpdateError::Kind::Failed,
                          "lost the system bus during the install: " + busErrnoText(r));
      }
      if (r > 0) continue;  // more may be queued
      r = sd_bus_wait(bus.get(), kWaitTickUs);
      if (r < 0 && r != -EINTR) {
        throw UpdateError(UpdateError::Kind::Failed,
                          "lost the system bus during the install: " + busErrnoText(r));
      }
    }
    if (*watch.completed != 0) {
      std::string message = bus.stringProperty("LastError");
      if (message.empty()) message = "RAUC failed with code " + std::to_string(*watch.completed);
      throw UpdateError(UpdateError::Kind::Failed, message);
    }
  }

  std::vector<SlotStatus> slots() override {
    Bus bus;
    BusError e;
    Message reply;
    int r = sd_bus_call_method(bus.get(), kService, kObject, kInterface, "GetSlotStatus", &e.error,
                               &reply.p, "");
    if (r < 0) Bus::fail(e, r, "GetSlotStatus", UpdateError::Kind::Failed);
    std::vector<SlotStatus> out;
    r = sd_bus_message_enter_container(reply.p, 'a', "(sa{sv})");
    if (r < 0) badReply(r, "GetSlotStatus");
    while ((r = sd_bus_message_enter_container(reply.p, 'r', "sa{sv}")) > 0) {
      out.push_back(readSlot(reply.p));
      r = sd_bus_message_exit_container(reply.p);
      if (r < 0) badReply(r, "GetSlotStatus");
    }
    if (r < 0) badReply(r, "GetSlotStatus");
    return out;
  }

  std::string compatible() override { return Bus().stringProperty("Compatible"); }

  std::string bootSlot() override { return Bus().stringProperty("BootSlot"); }
};

#else  // without libsystemd there is no way to reach RAUC

class RaucInstaller final : public UpdateInstaller {
 public:
  BundleInfo info(const std::filesystem::path& /*bundle*/) override { unavailable(); }
  void install(const std::filesystem::path& /*bundle*/, const InstallProgress& /*progress*/,
               std::stop_token /*stop*/) override {
    unavailable();
  }
  std::vector<SlotStatus> slots() override { unavailable(); }
  std::string compatible() override { unavailable(); }
  std::string bootSlot() override { unavailable(); }

 private:
  [[noreturn]] static void unavailable() {
    throw UpdateError(UpdateError::Kind::Unavailable,
                      std::string(kUnavailable) + ": built without libsystemd");
  }
};

#endif

}  // namespace

std::unique_ptr<UpdateInstaller> makeRaucInstaller() {
  return std::make_unique<RaucInstaller>();
}

}  // namespace cylscan::firmware
