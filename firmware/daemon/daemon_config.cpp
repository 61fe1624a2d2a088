// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/daemon_config.hpp"

#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include <toml++/toml.h>

#include "drivers/board_profile.hpp"
#include "firmware/shipped_boards.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;

std::string describe(const std::string& file, int line, const std::string& key,
                     const std::string& fault) {
  std::ostringstream out;
  out << file;
  if (line > 0) out << ":" << line;
  out << ": ";
  if (!key.empty()) out << key << ": ";
  out << fault;
  return out.str();
}

// One key's node with what the messages need.
struct Entry {
  const toml::node& node;
  std::string key;  // dotted, e.g. "daemon.listen"
  const std::string& file;
  int line() const { return static_cast<int>(node.source().begin.line); }
  [[noreturn]] void fail(const std::string& fault) const {
    throw ConfigError(file, line(), key, fault);
  }
  std::string string() const {
    if (!node.is_string()) fail("must be a string");
    return *node.value<std::string>();
  }
  bool boolean() const {
    if (!node.is_boolean()) fail("must be true or false");
    return *node.value<bool>();
  }
  std::int64_t integer(std::int64_t lo, std::int64_t hi) const {
    if (!node.is_integer()) fail("must be an integer");
    const std::int64_t v = *node.value<std::int64_t>();
    if (v < lo || v > hi)
      fail(std::to_string(v) + " is not in " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }
  fs::path path() const {
    const std::string s = string();
    if (s.empty()) fail("must not be empty");
    const fs::path p(s);
    return p.is_absolute() ? p : fs::path(file).parent_path() / p;
  }
};

using Handler = std::function<void(const Entry&)>;

void readTable(const toml::table& table, const std::string& section, const std::string& file,
               const std::map<std::string, Handler, std::less<>>& handlers) {
  for (const auto& [key, node] : table) {
    const std::string dotted = section + "." + std::string(key.str());
    auto it = handlers.find(key.str());
    if (it == handlers.end()) {
      throw ConfigError(file, static_cast<int>(key.source().begin.line), dotted, "unknown key");
    }
    it->second(Entry{node, dotted, file});
  }
}

std::optional<std::uint16_t> parsePort(std::string_view s) {
  if (s.empty() || s.size() > 5) return std::nullopt;
  unsigned v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v > 65535) return std::nullopt;
  return static_cast<std::uint16_t>(v);
}

}  // namespace

ConfigError::ConfigError(const std::string& file, int line, const std::string& key,
                         const std::string& fault)
    : std::invalid_argument(describe(file, line, key, fault)),
      file_(file),
      line_(line),
      key_(key) {}

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
  toml::table root;
  try {
    root = toml::parse(text, file);
  } catch (const toml::parse_error& e) {
    throw ConfigError(file, static_cast<int>(e.source().begin.line), "",
                      std::string(e.description()));
  }
  c.file = file_path;
  const std::map<std::string, Handler, std::less<>> daemon = {
      {"board", [&](const Entry& e) { c.board = e.path(); }},
      {"listen",
       [&](const Entry& e) {
         try {
           c.listen = parseListenAddress(e.string());
         } catch (const std::invalid_argument& err) {
           e.fail(err.what());
         }
       }},
      {"token",
       [&](const Entry& e) {
         c.token = e.string();
         for (char ch : c.token)
           if (ch <= ' ' || ch == 0x7f) e.fail("must not hold spaces or control characters");
       }},
      {"allow_loopback_without_token",
       [&](const Entry& e) { c.allow_loopback_without_token = e.boolean(); }},
      {"data_dir", [&](const Entry& e) { c.data_dir = e.path(); }},
      {"web_root", [&](const Entry& e) { c.web_root = e.path(); }},
      {"log_level",
       [&](const Entry& e) {
         try {
           c.log_level = parseLogLevel(e.string());
         } catch (const std::invalid_argument& err) {
           e.fail(err.what());
         }
       }},
      {"max_calibration_bytes",
       [&](const Entry& e) {
         c.max_calibration_bytes =
             static_cast<std::uint64_t>(e.integer(1024, std::int64_t{1} << 34));
       }},
  };
  const std::map<std::string, Handler, std::less<>> retention = {
      {"max_scans",
       [&](const Entry& e) {
         c.retention.max_scans = static_cast<std::uint64_t>(e.integer(0, 1000000));
       }},
      {"max_bytes",
       [&](const Entry& e) {
         c.retention.max_bytes = static_cast<std::uint64_t>(e.integer(0, INT64_MAX));
       }},
  };
  const std::map<std::string, Handler, std::less<>> scan = {
      {"mode",
       [&](const Entry& e) {
         const std::string m = e.string();
         if (m != "stop" && m != "continuous") e.fail("'" + m + "' is not stop or continuous");
         c.scan.mode = m;
       }},
      {"frames", [&](const Entry& e) { c.scan.frames = static_cast<int>(e.integer(3, 1000)); }},
      {"save_bundle", [&](const Entry& e) { c.scan.save_bundle = e.boolean(); }},
      {"phase",
       [&](const Entry& e) {
         const std::string p = e.string();
         if (p != "fused" && p != "high") e.fail("'" + p + "' is not fused or high");
         c.scan.phase = p;
       }},
  };
  const std::map<std::string, const std::map<std::string, Handler, std::less<>>*, std::less<>>
      sections = {{"daemon", &daemon}, {"retention", &retention}, {"scan", &scan}};
  for (const auto& [key, node] : root) {
    const int line = static_cast<int>(key.source().begin.line);
    auto it = sections.find(key.str());
    if (it == sections.end()) throw ConfigError(file, line, std::string(key.str()), "unknown key");
    if (!node.is_table())
      throw ConfigError(file, line, std::string(key.str()),
                        "must be a table [" + std::string(key.str()) + "]");
    readTable(*node.as_table(), std::string(key.str()), file, *it->second);
  }
  return c;
}

DaemonConfig loadDaemonConfig(const fs::path& file, DaemonConfig base) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file.string(), 0, "", "cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ConfigError(file.string(), 0, "", "cannot read the file");
  return parseDaemonConfig(text.str(), file, std::move(base));
}

DaemonConfig resolveDaemonConfig(const DaemonFlags& flags, const DaemonDefaults& defaults,
                                 const fs::path& system_config) {
  DaemonConfig c;
  c.board = defaults.board;
  c.data_dir = defaults.data_dir;
  c.web_root = defaults.web_root;
  std::error_code ec;
  if (flags.config)
    c = loadDaemonConfig(*flags.config, std::move(c));
  else if (!system_config.empty() && fs::exists(system_config, ec))
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
                          kSystemConfigFile.string());
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
