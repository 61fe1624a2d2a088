// SPDX-License-Identifier: Apache-2.0
// board.toml: loadBoardProfile and the firmware's readScanProfile on the input, written as
// board.toml in a folder that also holds the virtual head's head.toml and scenes/ (linked from
// board/sim), so profiles naming them reach the head model too. Every fault must be a
// drivers::ConfigError (the documented std::invalid_argument).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>

#include "drivers/board_profile.hpp"
#include "firmware/scan_profile.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

const std::filesystem::path& boardDir() {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = cylscan::fuzz::scratchDir() / "board";
    std::filesystem::create_directories(d);
    const std::filesystem::path sim = std::filesystem::path(CYLSCAN_SOURCE_DIR) / "board" / "sim";
    std::filesystem::create_symlink(sim / "head.toml", d / "head.toml");
    std::filesystem::create_directory_symlink(sim / "scenes", d / "scenes");
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file = boardDir() / "board.toml";
  cylscan::fuzz::writeFile(file, cylscan::fuzz::asText(data, size));
  try {
    const cylscan::drivers::BoardProfile profile = cylscan::drivers::loadBoardProfile(file);
    if (profile.cameras.empty() || profile.cameras.front().name != "main")
      throw std::logic_error("a profile accepted without \"main\" first");
    (void)cylscan::firmware::readScanProfile(profile);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
