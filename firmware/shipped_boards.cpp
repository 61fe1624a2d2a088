// SPDX-License-Identifier: Apache-2.0
#include "firmware/shipped_boards.hpp"

#include <system_error>

namespace cylscan::firmware {

namespace fs = std::filesystem;

fs::path shippedBoard(const fs::path& exe_dir, std::string_view name) {
  const fs::path installed = exe_dir / ".." / "share" / "cylscan" / "board" / name;
  std::error_code ec;
  if (fs::is_directory(installed, ec)) return installed.lexically_normal();
  return fs::path(CYLSCAN_SOURCE_BOARD_ROOT) / name;
}

fs::path shippedBoard(std::string_view name) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return shippedBoard(ec ? fs::path(".") : exe.parent_path(), name);
}

}  // namespace cylscan::firmware
