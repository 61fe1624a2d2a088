// SPDX-License-Identifier: Apache-2.0
// The daemon's configuration: cylscan.toml (format in docs/daemon.md), the
// command-line flags that override it, and the defaults of the virtual head
// when there is neither.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/toml_reader.hpp"

namespace cylscan::firmware {

// A fault of the configuration: "FILE:LINE: KEY: FAULT" (line 0 = not known,
// e.g. a flag; the file is then "--flag"). The one strict TOML reader's error.
using drivers::ConfigError;

enum class LogLevel { Error, Warn, Info, Debug };
// "error" | "warn" | "info" | "debug"; std::invalid_argument otherwise.
LogLevel parseLogLevel(std::string_view name);
std::string_view toString(LogLevel level);

struct ListenAddress {
  std::string address = "127.0.0.1";  // IPv4 or IPv6 literal (without brackets)
  std::uint16_t port = 8080;          // 0: any free port
};
// "ADDRESS:PORT", IPv6 as "[::1]:8080"; std::invalid_argument saying why not.
ListenAddress parseListenAddress(std::string_view text);
std::string toString(const ListenAddress& listen);  // "127.0.0.1:8080", "[::1]:8080"

struct RetentionConfig {
  std::uint64_t max_scans = 100;            // 0 = no limit
  std::uint64_t max_bytes = 4294967296ull;  // 0 = no limit
};

// Defaults of POST /api/v1/scans; absent = the board profile's.
struct ScanDefaults {
  std::optional<std::string> mode;  // "stop" | "continuous"
  std::optional<int> frames;        // 3..1000
  std::optional<bool> save_bundle;
  std::optional<std::string> phase;  // "fused" | "high"
};

// [update]: A/B updates through PUT /api/v1/system/update.
struct UpdateConfig {
  std::uint64_t max_bundle_bytes = 1ull << 30;  // larger bundles are 413
  bool reboot = true;  // ask the image to reboot after a successful install
};

struct DaemonConfig {
  std::filesystem::path file;  // the cylscan.toml read; empty when none
  std::filesystem::path board;
  ListenAddress listen;
  std::string token;  // empty: no authentication
  bool allow_loopback_without_token = false;
  std::filesystem::path data_dir;
  std::filesystem::path web_root;
  LogLevel log_level = LogLevel::Info;
  std::uint64_t max_calibration_bytes = 134217728;
  RetentionConfig retention;
  ScanDefaults scan;
  UpdateConfig update;
};

// Where the virtual head and its page are when nothing is configured.
struct DaemonDefaults {
  std::filesystem::path board;
  std::filesystem::path data_dir;
  std::filesystem::path web_root;
};
// For an executable in `exe_dir`: <exe_dir>/../share/cylscan/board/sim and
// …/web when installed, else the source tree's board/sim and the build
// tree's web/dist; data in $XDG_STATE_HOME/cylscan or ~/.local/state/cylscan.
// A build without the virtual head has no default board (board empty).
DaemonDefaults daemonDefaults(const std::filesystem::path& exe_dir);

// Parses the text of a cylscan.toml over `base` (keys absent keep base's
// values). `file` names it in messages and anchors relative paths. Unknown
// keys, wrong types and impossible values throw ConfigError.
DaemonConfig parseDaemonConfig(std::string_view text, const std::filesystem::path& file,
                               DaemonConfig base);
// Reads the file; ConfigError (line 0) when it cannot be read.
DaemonConfig loadDaemonConfig(const std::filesystem::path& file, DaemonConfig base);

// The command line (every flag optional).
struct DaemonFlags {
  // Each --config in turn over the last: a later file sets only its own keys
  // (an image lays its per-head settings over the packaged file this way).
  std::vector<std::filesystem::path> configs;
  std::optional<std::filesystem::path> board, data_dir, web_root;
  std::optional<std::string> listen, token, log_level;
};

inline constexpr std::string_view kSystemConfigFile = "/etc/cylscan/cylscan.toml";

// The defaults, then the config files (every --config in order, else
// `system_config` when it exists), then the flags. ConfigError for any
// fault, and when none of them gives a board.
DaemonConfig resolveDaemonConfig(const DaemonFlags& flags, const DaemonDefaults& defaults,
                                 const std::filesystem::path& system_config = kSystemConfigFile);

}  // namespace cylscan::firmware
