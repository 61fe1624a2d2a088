// SPDX-License-Identifier: Apache-2.0
// The daemon's ScanService on a tiny virtual head (board/sim at 16×16 pixels,
// its scenes/ linked), made once per fuzzing process: the targets that fuzz
// what the service validates (scan options, calibration uploads) call it
// as the HTTP layer does, without sockets. Its worker stays idle.
#pragma once

#include <filesystem>
#include <memory>
#include <regex>
#include <string>

#include "firmware/daemon/scan_service.hpp"
#include "fuzz/fuzz_support.hpp"

namespace cylscan::fuzz {

inline constexpr int kSmallWidth = 16;
inline constexpr int kSmallHeight = 16;

inline firmware::ScanService& smallService() {
  static const std::unique_ptr<firmware::ScanService> service = [] {
    namespace fs = std::filesystem;
    const fs::path sim = fs::path(CYLSCAN_SOURCE_DIR) / "board" / "sim";
    const fs::path board = scratchDir() / "board";
    fs::create_directories(board);
    std::string s = readFile(sim / "board.toml");
    s = std::regex_replace(s, std::regex("width = 1000"), "width = " + std::to_string(kSmallWidth));
    s = std::regex_replace(s, std::regex("height = 800"),
                           "height = " + std::to_string(kSmallHeight));
    s = s.substr(0, s.rfind("\n[sim]") + 1);
    s += "[sim]\nhead = \"" + (sim / "head.toml").string() +
         "\"\nscene = \"scenes/sphere_on_plane.toml\"\nseed = 1\nresolution = [" +
         std::to_string(kSmallWidth) + ", " + std::to_string(kSmallHeight) + "]\n";
    writeFile(board / "board.toml", s);
    fs::create_directory_symlink(sim / "scenes", board / "scenes");
    firmware::ScanServiceOptions options;
    options.board = board;
    options.data_dir = scratchDir() / "data";
    options.max_calibration_bytes = 1u << 20;
    return std::make_unique<firmware::ScanService>(options);
  }();
  return *service;
}

}  // namespace cylscan::fuzz
