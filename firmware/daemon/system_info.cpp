// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/system_info.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <iterator>
#include <system_error>

namespace cylscan::firmware {

std::optional<std::string> bootedSlot(std::string_view line) {
  constexpr std::string_view kKey = "rauc.slot=";
  std::size_t at = 0;
  while (at < line.size()) {
    const std::size_t end = std::min(line.find_first_of(" \t\n", at), line.size());
    const std::string_view word = line.substr(at, end - at);
    if (word.substr(0, kKey.size()) == kKey) {
      const std::string_view slot = word.substr(kKey.size());
      if (slot == "a" || slot == "b") return std::string(slot);
      return std::nullopt;  // not a slot an image has
    }
    at = end + 1;
  }
  return std::nullopt;
}

SystemInfo::SystemInfo(std::string version, std::filesystem::path data_dir,
                       std::filesystem::path command_line)
    : version_(std::move(version)),
      data_dir_(std::move(data_dir)),
      command_line_(std::move(command_line)) {}

nlohmann::json SystemInfo::report() const {
  std::array<char, 256> name{};
  const std::string hostname =
      gethostname(name.data(), name.size() - 1) == 0 ? std::string(name.data()) : std::string();
  std::ifstream in(command_line_);
  const std::string line{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const std::optional<std::string> slot = bootedSlot(line);
  std::error_code ec;
  const std::filesystem::space_info space = std::filesystem::space(data_dir_, ec);
  nlohmann::json data = nullptr;
  if (!ec) data = {{"total_bytes", space.capacity}, {"free_bytes", space.available}};
  return {{"version", version_},
          {"hostname", hostname},
          {"slot", slot ? nlohmann::json(*slot) : nlohmann::json(nullptr)},
          {"data", data}};
}

}  // namespace cylscan::firmware
