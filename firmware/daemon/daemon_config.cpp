// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/daemon_config.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstdlib>

#include <toml++/toml.h>

#include "drivers/board_profile.hpp"
#include "drivers/toml_reader.hpp"
#include "firmware/shipped_boards.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;

std::optional<std::uint16_t> parsePort(std::string_view s) {
  if (s.empty() || s.size() > 5) return std::nullopt;
  unsigned v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v > 65535) return std::nullopt;
  return static_cast<std::uint16_t>(v);
}

}  // namespace

LogLevel parseLogLevel(std::string_view name) {
  if (name == "error") return LogLevel::Error;
  if (name == "warn") return LogLevel::Warn;
  if (name == "info") return LogLevel::Info;
  if (name == "debug") return LogLevel::Debug;
  throw std::invalid_argument("'" + std::string(name) + "' is not error, warn, info or debug");
}

std::string_view toString(LogLevel level) {
  switch (level) {
    case LogLevel::Error:
      return "error";
    case LogLevel::Warn:
      return "warn";
    case LogLevel::Info:
      return "info";
    case LogLevel::Debug:
      return "debug";
  }
  return "info";
}

ListenAddress parseListenAddress(std::string_view text) {
  const auto bad = [&] {
    return std::invalid_argument("'" + std::string(text) + "' is not ADDRESS:PORT");
  };
  ListenAddress out;
  std::string_view port;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string_view::npos || close + 1 >= text.size() || text[close + 1] != ':')
      throw bad();
    out.address = std::string(text.substr(1, close - 1));
    port = text.substr(close + 2);
    if (out.address.empty() || out.address.find(':') == std::string::npos) throw bad();
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string_view::npos || colon == 0) throw bad();
    out.address = std::string(text.substr(0, colon));
    port = text.substr(colon + 1);
    if (out.address.find(':') != std::string::npos) throw bad();  // IPv6 needs brackets
  }
  for (char c : out.address) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == ':' || c == '-';
    if (!ok) throw bad();
  }
  const auto p = parsePort(port);
  if (!p) throw bad();
  out.port = *p;
  return out;
}

std::string toString(const ListenAddress& listen) {
  const bool v6 = listen.address.find(':') != std::string::npos;
  return (v6 ? "[" + listen.address + "]" : listen.address) + ":" + std::to_string(listen.port);
}

DaemonDefaults daemonDefaults(const fs::path& exe_dir) {
  DaemonDefaults d;
  const fs::path share = exe_dir / ".." / "share" / "cylscan";
  std::error_code ec;
  // Without the virtual head there is no board to default to: resolveDaemonConfig asks for one.
  if (drivers::virtualHeadBuilt()) d.board = firmware::shippedBoard(exe_dir, "sim");
  d.web_root = fs::is_directory(share / "web", ec) ? (share / "web").lexically_normal()
                                                   : fs::path(CYLSCAN_BUILD_WEB_DIR);
  // getenv is not thread-safe against setenv: called from main before any
  // thread starts, and nothing in the daemon sets the environment.
  // NOLINTNEXTLINE(concurrency-mt-unsafe)
  if (const char* state = std::getenv("XDG_STATE_HOME");
      state && *state && fs::path(state).is_absolute())
    d.data_dir = fs::path(state) / "cylscan";
  // NOLINTNEXTLINE(concurrency-mt-unsafe)
  else if (const char* home = std::getenv("HOME"); home && *home)
    d.data_dir = fs::path(home) / ".local" / "state" / "cylscan";
  else
    d.data_dir = fs::temp_directory_path() / "cylscan";
  return d;
}

DaemonConfig parseDaemonConfig(std::string_view text, const fs::path& file_path, DaemonConfig c) {
  const std::string file = file_path.string();
  const toml::table root = drivers::parseToml(text, file);
  c.file = file_path;
  drivers::TableReader top(root, file, "");
  // A value that a parser of its own checks: its std::invalid_argument names the key.
  const auto checked = [](drivers::TableReader& r, std::string_view key, auto parse) {
    try {
      return parse(r.string(key, ""));
    } catch (const std::invalid_argument& e) {
      r.fail(key, e.what());
    }
  };
  if (const toml::table* t = top.table("daemon")) {
    drivers::TableReader r(*t, file, "daemon");
    c.board = r.path("board", c.board);
    if (r.has("listen")) c.listen = checked(r, "listen", parseListenAddress);
    c.token = r.string("token", c.token);
    r.require(std::none_of(c.token.begin(), c.token.end(),
                           [](char ch) { return ch <= ' ' || ch == 0x7f; }),
              "token", "must not hold spaces or control characters");
    c.allow_loopback_without_token =
        r.boolean("allow_loopback_without_token", c.allow_loopback_without_token);
    c.data_dir = r.path("data_dir", c.data_dir);
    c.web_root = r.path("web_root", c.web_root);
    if (r.has("log_level")) c.log_level = checked(r, "log_level", parseLogLevel);
    c.max_calibration_bytes = static_cast<std::uint64_t>(
        r.integerIn("max_calibration_bytes", static_cast<std::int64_t>(c.max_calibration_bytes),
                    1024, std::int64_t{1} << 34));
    r.finish();
  }
  if (const toml::table* t = top.table("update")) {
    drivers::TableReader r(*t, file, "update");
    c.update.max_bundle_bytes = static_cast<std::uint64_t>(
        r.integerIn("max_bundle_bytes", static_cast<std::int64_t>(c.update.max_bundle_bytes), 1024,
                    std::int64_t{1} << 40));
    c.update.reboot = r.boolean("reboot", c.update.reboot);
    r.finish();
  }
  if (const toml::table* t = top.table("retention")) {
    drivers::TableReader r(*t, file, "retention");
    c.retention.max_scans = static_cast<std::uint64_t>(
        r.integerIn("max_scans", static_cast<std::int64_t>(c.retention.max_scans), 0, 1000000));
    c.retention.max_bytes = static_cast<std::uint64_t>(
        r.integerIn("max_bytes", static_cast<std::int64_t>(c.retention.max_bytes), 0, INT64_MAX));
    r.finish();
  }
  if (const toml::table* t = top.table("scan")) {
    drivers::TableReader r(*t, file, "scan");
    if (r.has("mode")) {
      const std::string m = r.string("mode", "");
      r.require(m == "stop" || m == "continuous", "mode", "'" + m + "' is not stop or continuous");
      c.scan.mode = m;
    }
    if (r.has("frames")) c.scan.frames = static_cast<int>(r.integerIn("frames", 0, 3, 1000));
    if (r.has("save_bundle")) c.scan.save_bundle = r.boolean("save_bundle", false);
    if (r.has("phase")) {
      const std::string p = r.string("phase", "");
      r.require(p == "fused" || p == "high", "phase", "'" + p + "' is not fused or high");
      c.scan.phase = p;
    }
    r.finish();
  }
  top.finish();
  return c;
}

DaemonConfig loadDaemonConfig(const fs::path& file, DaemonConfig base) {
  return parseDaemonConfig(drivers::readConfigText(file.string()), file, std::move(base));
}

DaemonConfig resolveDaemonConfig(const DaemonFlags& flags, const DaemonDefaults& defaults,
                                 const fs::path& system_config) {
  DaemonConfig c;
  c.board = defaults.board;
  c.data_dir = defaults.data_dir;
  c.web_root = defaults.web_root;
  std::error_code ec;
  for (const fs::path& file : flags.configs)
    c = loadDaemonConfig(file, std::move(c));
  if (flags.configs.empty() && !system_config.empty() && fs::exists(system_config, ec))
    c = loadDaemonConfig(system_config, std::move(c));
  const auto nonEmpty = [](const fs::path& p, const char* flag) {
    if (p.empty()) throw ConfigError(flag, 0, "", "must not be empty");
    return p;
  };
  if (flags.board) c.board = nonEmpty(*flags.board, "--board");
  if (c.board.empty()) {
    throw ConfigError("--board", 0, "",
                      "no board profile configured, and " + std::string(drivers::kNoVirtualHead) +
                          " to default to: give --board DIR or [daemon] board in " +
                          std::string(kSystemConfigFile));
  }
  if (flags.data_dir) c.data_dir = nonEmpty(*flags.data_dir, "--data");
  if (flags.web_root) c.web_root = nonEmpty(*flags.web_root, "--web-root");
  if (flags.token) c.token = *flags.token;
  if (flags.listen) {
    try {
      c.listen = parseListenAddress(*flags.listen);
    } catch (const std::invalid_argument& e) {
      throw ConfigError("--listen", 0, "", e.what());
    }
  }
  if (flags.log_level) {
    try {
      c.log_level = parseLogLevel(*flags.log_level);
    } catch (const std::invalid_argument& e) {
      throw ConfigError("--log-level", 0, "", e.what());
    }
  }
  return c;
}

}  // namespace cylscan::firmware
