// SPDX-License-Identifier: Apache-2.0
// Helpers for the board-profile tests: profiles written to a temporary
// folder, and the repository's board folders.
#pragma once

#include "tests/support/temp_dir.hpp"

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "drivers/board_profile.hpp"
#include "drivers/toml_reader.hpp"
#include "firmware/scan_profile.hpp"

namespace cylscan::drivers::test {

inline std::filesystem::path boardDir(const std::string& name) {
  return std::filesystem::path(CYLSCAN_SOURCE_DIR) / "board" / name;
}

// A folder of its own per test, removed at the end.
using test_support::TempDir;

// A valid hardware profile; tests append to it or replace parts of it.
inline std::string hardwareGpio() {
  return R"([board]
name = "test"

[gpio]
step = { name = "GPIO17" }
dir = { name = "GPIO27" }
enable = { chip = "gpiochip0", offset = 22, active_low = true }
light = { name = "GPIO24" }
home = { name = "GPIO25" }
trigger = { name = "GPIO23" }
)";
}

inline std::string v4l2Main() {
  return R"(
[[camera]]
name = "main"
backend = "v4l2"
device = "/dev/video0"
)";
}

// The ConfigError of loading `text` as a board.toml.
inline drivers::ConfigError profileError(const TempDir& dir, const std::string& text) {
  const auto file = dir.write("board.toml", text);
  try {
    loadBoardProfile(dir.path());
  } catch (const drivers::ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "the profile loaded:\n" << text;
  return drivers::ConfigError(file.string(), 0, "", "no error");
}

// The ConfigError of reading the [scan] of `text` (a board.toml the drivers accept).
inline drivers::ConfigError scanError(const TempDir& dir, const std::string& text) {
  const auto file = dir.write("board.toml", text);
  try {
    firmware::readScanProfile(loadBoardProfile(dir.path()));
  } catch (const drivers::ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "the [scan] was read:\n" << text;
  return drivers::ConfigError(file.string(), 0, "", "no error");
}

}  // namespace cylscan::drivers::test
