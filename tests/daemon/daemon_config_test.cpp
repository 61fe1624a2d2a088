// SPDX-License-Identifier: Apache-2.0
// cylscan.toml and the flags of cylscand: every key read, every fault named by
// file, line and key, flags over the file, relative paths anchored at the
// file's folder.
#include "firmware/daemon/daemon_config.hpp"

#include <string>

#include <gtest/gtest.h>

#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using test_support::TempDir;

const char* kFull = R"([daemon]
board = "boards/sim"
listen = "[::1]:9090"
token = "s3cret"
allow_loopback_without_token = true
data_dir = "/var/lib/cylscan-test"
web_root = "web"
log_level = "debug"
max_calibration_bytes = 1048576
[retention]
max_scans = 7
max_bytes = 5000000000
[scan]
mode = "continuous"
frames = 12
save_bundle = true
phase = "high"
)";

DaemonConfig base() {
  DaemonConfig c;
  c.board = "/default/board";
  c.data_dir = "/default/data";
  c.web_root = "/default/web";
  return c;
}

TEST(DaemonConfig, ReadsEveryKey) {
  const DaemonConfig c = parseDaemonConfig(kFull, "/etc/cs/cylscan.toml", base());
  EXPECT_EQ(c.file, fs::path("/etc/cs/cylscan.toml"));
  EXPECT_EQ(c.board, fs::path("/etc/cs/boards/sim"));  // relative to the file's folder
  EXPECT_EQ(c.listen.address, "::1");
  EXPECT_EQ(c.listen.port, 9090);
  EXPECT_EQ(c.token, "s3cret");
  EXPECT_TRUE(c.allow_loopback_without_token);
  EXPECT_EQ(c.data_dir, fs::path("/var/lib/cylscan-test"));
  EXPECT_EQ(c.web_root, fs::path("/etc/cs/web"));
  EXPECT_EQ(c.log_level, LogLevel::Debug);
  EXPECT_EQ(c.max_calibration_bytes, 1048576u);
  EXPECT_EQ(c.retention.max_scans, 7u);
  EXPECT_EQ(c.retention.max_bytes, 5000000000ull);
  EXPECT_EQ(c.scan.mode, "continuous");
  EXPECT_EQ(c.scan.frames, 12);
  EXPECT_EQ(c.scan.save_bundle, true);
  EXPECT_EQ(c.scan.phase, "high");
}

TEST(DaemonConfig, AbsentKeysKeepTheDefaults) {
  const DaemonConfig c = parseDaemonConfig("[daemon]\nlog_level = \"warn\"\n", "c.toml", base());
  EXPECT_EQ(c.board, fs::path("/default/board"));
  EXPECT_EQ(c.data_dir, fs::path("/default/data"));
  EXPECT_EQ(c.listen.address, "127.0.0.1");
  EXPECT_EQ(c.listen.port, 8080);
  EXPECT_EQ(c.retention.max_scans, 100u);
  EXPECT_FALSE(c.scan.mode.has_value());
  EXPECT_FALSE(c.scan.frames.has_value());
  EXPECT_EQ(c.log_level, LogLevel::Warn);
}

TEST(DaemonConfig, ReadsTheUpdateKeys) {
  const DaemonConfig d = parseDaemonConfig("", "c.toml", base());
  EXPECT_EQ(d.update.max_bundle_bytes, std::uint64_t{1} << 30);
  EXPECT_TRUE(d.update.reboot);
  const DaemonConfig c =
      parseDaemonConfig("[update]\nmax_bundle_bytes = 2000000\nreboot = false\n", "c.toml", base());
  EXPECT_EQ(c.update.max_bundle_bytes, 2000000u);
  EXPECT_FALSE(c.update.reboot);
}

// The message of parsing `text`, which must fail.
std::string faultOf(const std::string& text) {
  try {
    parseDaemonConfig(text, "cylscan.toml", base());
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(DaemonConfig, EachFaultNamesFileLineAndKey) {
  EXPECT_EQ(faultOf("[daemon]\n\n\nlisten = \"localhost:99999\"\n"),
            "cylscan.toml:4: daemon.listen: 'localhost:99999' is not ADDRESS:PORT");
  struct Case {
    std::string text;
    std::string prefix;
  };
  const Case cases[] = {
      {"[daemon]\nboard = 3\n", "cylscan.toml:2: daemon.board: must be a string"},
      {"[update]\nmax_bundle_bytes = 10\n", "cylscan.toml:2: update.max_bundle_bytes:"},
      {"[update]\nreboot = 1\n", "cylscan.toml:2: update.reboot:"},
      {"[update]\nrestart = true\n", "cylscan.toml:2: update.restart"},
      {"[daemon]\nlisten = \"1.2.3.4\"\n", "cylscan.toml:2: daemon.listen:"},
      {"[daemon]\nlisten = \"::1:80\"\n", "cylscan.toml:2: daemon.listen:"},
      {"[daemon]\ntoken = \"a b\"\n", "cylscan.toml:2: daemon.token:"},
      {"[daemon]\nallow_loopback_without_token = \"yes\"\n",
       "cylscan.toml:2: daemon.allow_loopback_without_token: must be true or false"},
      {"[daemon]\ndata_dir = \"\"\n", "cylscan.toml:2: daemon.data_dir: must not be empty"},
      {"[daemon]\nweb_root = 1.5\n", "cylscan.toml:2: daemon.web_root: must be a string"},
      {"[daemon]\nlog_level = \"loud\"\n", "cylscan.toml:2: daemon.log_level:"},
      {"[daemon]\nmax_calibration_bytes = -1\n", "cylscan.toml:2: daemon.max_calibration_bytes:"},
      {"[daemon]\nlisten = \"127.0.0.1:80\"\ncolour = 1\n",
       "cylscan.toml:3: daemon.colour: unknown key"},
      {"[retention]\nmax_scans = \"ten\"\n",
       "cylscan.toml:2: retention.max_scans: must be an integer"},
      {"[retention]\nmax_bytes = -5\n", "cylscan.toml:2: retention.max_bytes:"},
      {"[scan]\nmode = \"fast\"\n", "cylscan.toml:2: scan.mode: 'fast' is not stop or continuous"},
      {"[scan]\nframes = 2\n", "cylscan.toml:2: scan.frames: 2 is not in 3..1000"},
      {"[scan]\nframes = 2.5\n", "cylscan.toml:2: scan.frames: must be an integer"},
      {"[scan]\nsave_bundle = 1\n", "cylscan.toml:2: scan.save_bundle: must be true or false"},
      {"[scan]\nphase = \"low\"\n", "cylscan.toml:2: scan.phase: 'low' is not fused or high"},
      {"[server]\nport = 1\n", "cylscan.toml:1: server: unknown key"},
      {"daemon = 3\n", "cylscan.toml:1: daemon: must be a table"},
      {"[daemon]\nlisten = \n", "cylscan.toml:2:"},  // a syntax error: its line
  };
  for (const Case& c : cases) {
    const std::string fault = faultOf(c.text);
    EXPECT_EQ(fault.substr(0, c.prefix.size()), c.prefix) << c.text;
  }
}

TEST(DaemonConfig, ListenAddresses) {
  EXPECT_EQ(parseListenAddress("0.0.0.0:0").port, 0);
  EXPECT_EQ(parseListenAddress("[::]:443").address, "::");
  EXPECT_EQ(toString(parseListenAddress("[::1]:8080")), "[::1]:8080");
  EXPECT_EQ(toString(parseListenAddress("127.0.0.1:80")), "127.0.0.1:80");
  for (const char* bad : {"", ":80", "127.0.0.1:", "127.0.0.1:65536", "127.0.0.1:8o", "[::1]80",
                          "[]:80", "a b:80", "127.0.0.1:-1"}) {
    EXPECT_THROW(parseListenAddress(bad), std::invalid_argument) << bad;
  }
}

TEST(DaemonConfig, FlagsOverrideTheFile) {
  TempDir dir;
  const fs::path file = dir.write("cylscan.toml", kFull);
  DaemonFlags flags;
  flags.configs = {file};
  flags.board = "/flag/board";
  flags.listen = "127.0.0.1:0";
  flags.data_dir = "/flag/data";
  flags.token = "";
  flags.web_root = "/flag/web";
  flags.log_level = "error";
  const DaemonConfig c = resolveDaemonConfig(flags, {"/d/board", "/d/data", "/d/web"}, "");
  EXPECT_EQ(c.board, fs::path("/flag/board"));
  EXPECT_EQ(c.listen.port, 0);
  EXPECT_EQ(c.data_dir, fs::path("/flag/data"));
  EXPECT_EQ(c.token, "");
  EXPECT_EQ(c.web_root, fs::path("/flag/web"));
  EXPECT_EQ(c.log_level, LogLevel::Error);
  EXPECT_EQ(c.retention.max_scans, 7u);  // from the file
  EXPECT_EQ(c.scan.frames, 12);

  DaemonFlags bad;
  bad.listen = "nowhere";
  try {
    resolveDaemonConfig(bad, {"/d/board", "/d/data", "/d/web"}, "");
    ADD_FAILURE() << "a bad --listen must fail";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--listen"), std::string::npos) << e.what();
  }
}

TEST(DaemonConfig, WithoutFileOrFlagsTheDefaultsAndTheSystemFile) {
  TempDir dir;
  const DaemonDefaults defaults{"/d/board", "/d/data", "/d/web"};
  DaemonConfig c = resolveDaemonConfig({}, defaults, dir.path() / "missing.toml");
  EXPECT_TRUE(c.file.empty());
  EXPECT_EQ(c.board, fs::path("/d/board"));
  EXPECT_EQ(c.data_dir, fs::path("/d/data"));
  EXPECT_EQ(c.web_root, fs::path("/d/web"));
  EXPECT_EQ(toString(c.listen), "127.0.0.1:8080");

  const fs::path system = dir.write("system.toml", "[daemon]\nlisten = \"127.0.0.1:9000\"\n");
  c = resolveDaemonConfig({}, defaults, system);
  EXPECT_EQ(c.file, system);
  EXPECT_EQ(c.listen.port, 9000);

  DaemonFlags missing;
  missing.configs = {dir.path() / "nope.toml"};
  EXPECT_THROW(resolveDaemonConfig(missing, defaults, system), ConfigError);
}

// An image lays the head's own settings (token, listen address) over the
// packaged file: the later file sets only its keys, and the system file is
// not read when files are named.
TEST(DaemonConfig, LaterConfigFilesSetOnlyTheirOwnKeys) {
  TempDir dir;
  const fs::path packaged = dir.write("cylscan.toml", kFull);
  const fs::path head =
      dir.write("head.toml", "[daemon]\ntoken = \"t0k3n\"\nlisten = \"0.0.0.0:80\"\n");
  const fs::path system = dir.write("system.toml", "[retention]\nmax_scans = 3\n");
  DaemonFlags flags;
  flags.configs = {packaged, head};
  const DaemonConfig c = resolveDaemonConfig(flags, {"/d/board", "/d/data", "/d/web"}, system);
  EXPECT_EQ(c.token, "t0k3n");
  EXPECT_EQ(toString(c.listen), "0.0.0.0:80");
  EXPECT_EQ(c.retention.max_scans, 7u);  // the packaged file's, not the system file's
  EXPECT_EQ(c.scan.frames, 12);
  EXPECT_EQ(c.file, head);

  flags.configs = {head, packaged};  // the other way round, the packaged file wins
  EXPECT_NE(resolveDaemonConfig(flags, {"/d/board", "/d/data", "/d/web"}, system).token, "t0k3n");
}

TEST(DaemonConfig, TheVirtualHeadDefaultsOfABuildTree) {
  TempDir dir;  // an executable's folder with no share/cylscan next to it
  fs::create_directories(dir.path() / "bin");
  const DaemonDefaults d = daemonDefaults(dir.path() / "bin");
  EXPECT_TRUE(fs::exists(d.board / "board.toml")) << d.board;
  EXPECT_EQ(d.data_dir.filename(), "cylscan");
  fs::create_directories(dir.path() / "share/cylscan/board/sim");
  const DaemonDefaults installed = daemonDefaults(dir.path() / "bin");
  EXPECT_EQ(installed.board, (dir.path() / "share/cylscan/board/sim").lexically_normal());
}

}  // namespace
}  // namespace cylscan::firmware
