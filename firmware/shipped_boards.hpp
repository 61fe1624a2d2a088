// SPDX-License-Identifier: Apache-2.0
// Where the board profiles that ship with cylscan are: installed beside the
// programs (<prefix>/share/cylscan/board/<name>, as the .deb lays them out),
// or, for programs run from a build tree, the source tree's board/<name>.
#pragma once

#include <filesystem>
#include <string_view>

namespace cylscan::firmware {

// For a program in `exe_dir`.
std::filesystem::path shippedBoard(const std::filesystem::path& exe_dir, std::string_view name);
// For the running program (/proc/self/exe).
std::filesystem::path shippedBoard(std::string_view name);

}  // namespace cylscan::firmware
