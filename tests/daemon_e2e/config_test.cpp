// SPDX-License-Identifier: Apache-2.0
// A bad configuration is refused at start: cylscand exits 2, prints nothing
// on stdout (no listening line) and one line on stderr naming the file, the
// line and the key at fault.
#include <chrono>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

struct Refusal {
  int exit_code = -1000;
  std::string out, err;
};

Refusal runToExit(const TempDir& dir, const std::vector<std::string>& args) {
  DaemonProcess daemon(args, dir.path() / "stderr.txt");
  Refusal r;
  const auto status = daemon.waitExit(std::chrono::seconds(20));
  if (!status) {
    daemon.kill();
    ADD_FAILURE() << "cylscand did not exit within 20 s: " << daemon.stderrText();
    return r;
  }
  r.exit_code = DaemonProcess::exitCode(*status);
  r.out = daemon.stdoutText();
  r.err = daemon.stderrText();
  return r;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(line);
  return out;
}

struct BadConfig {
  std::string what, text;
  int line;
  std::string key;
};

TEST(DaemonConfig, BadConfigFileExits2NamingFileLineAndKey) {
  const std::vector<BadConfig> cases = {
      {"unknown key", "[daemon]\nlisten = \"127.0.0.1:0\"\nbogus_key = 1\n", 3, "bogus_key"},
      {"bad listen", "# a comment\n[daemon]\nlisten = \"nowhere\"\n", 3, "listen"},
      {"port out of range", "[daemon]\n\nlisten = \"127.0.0.1:70000\"\n", 3, "listen"},
      {"unknown section", "[daemon]\nlisten = \"127.0.0.1:0\"\n[extra]\nx = 1\n", 3, "extra"},
      {"unknown scan key", "[scan]\nframes = 10\nspeed = 3\n", 3, "speed"},
      {"bad scan value", "[scan]\nmode = \"sideways\"\n", 2, "mode"},
      {"wrong type", "[daemon]\ntoken = 42\n", 2, "token"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    TempDir dir;
    const fs::path file = dir.write("cylscan.toml", c.text);
    const Refusal r =
        runToExit(dir, {"--config", file.string(), "--data", (dir.path() / "data").string(),
                        "--board", (quickFixture() / "board").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(r.out.find("listening"), std::string::npos) << r.out;
    const auto err = lines(r.err);
    ASSERT_EQ(err.size(), 1u) << "one line on stderr:\n" << r.err;
    const std::string where = file.string() + ":" + std::to_string(c.line);
    EXPECT_NE(err[0].find(where), std::string::npos) << "names " << where << ": " << err[0];
    EXPECT_NE(err[0].find(c.key), std::string::npos) << "names " << c.key << ": " << err[0];
  }
}

TEST(DaemonConfig, BadFlagsExit2NamingTheFlag) {
  struct BadFlag {
    std::vector<std::string> args;
    std::string named;
  };
  TempDir dir;
  const std::vector<BadFlag> cases = {
      {{"--listen", "not-an-address"}, "--listen"},
      {{"--listen", "127.0.0.1:99999"}, "--listen"},
      {{"--config", (dir.path() / "missing.toml").string()}, "missing.toml"},
      {{"--board", (dir.path() / "no-board").string()}, "no-board"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.named);
    std::vector<std::string> args = {"--data", (dir.path() / "data").string()};
    if (c.args[0] != "--board") {
      args.push_back("--board");
      args.push_back((quickFixture() / "board").string());
    }
    args.insert(args.end(), c.args.begin(), c.args.end());
    const Refusal r = runToExit(dir, args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(r.out.find("listening"), std::string::npos) << r.out;
    const auto err = lines(r.err);
    ASSERT_EQ(err.size(), 1u) << "one line on stderr:\n" << r.err;
    EXPECT_NE(err[0].find(c.named), std::string::npos) << err[0];
  }
}

}  // namespace
}  // namespace cylscan::test
