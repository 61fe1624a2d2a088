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

std::optional<std::string> osReleaseValue(std::string_view text, std::string_view key) {
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view line = text.substr(at, end - at);
    at = end + 1;
    if (line.size() <= key.size() || line.substr(0, key.size()) != key || line[key.size()] != '=') {
      continue;
    }
    std::string_view value = line.substr(key.size() + 1);
    if (value.size() >= 2 && (value.front() == '"' || value.front() == '\'') &&
        value.back() == value.front()) {
      value = value.substr(1, value.size() - 2);
    }
    return std::string(value);
  }
  return std::nullopt;
}

namespace {

std::string readAll(const std::filesystem::path& file) {
  std::ifstream in(file);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

SystemInfo::SystemInfo(std::string version, std::filesystem::path data_dir,
                       std::filesystem::path command_line, std::filesystem::path os_release)
    : version_(std::move(version)),
      data_dir_(std::move(data_dir)),
      command_line_(std::move(command_line)),
      os_release_(std::move(os_release)) {}

nlohmann::json SystemInfo::report() const {
  std::array<char, 256> name{};
  const std::string hostname =
      gethostname(name.data(), name.size() - 1) == 0 ? std::string(name.data()) : std::string();
  const std::optional<std::string> slot = bootedSlot(readAll(command_line_));
  const std::string release = readAll(os_release_);
  const std::optional<std::string> image_id = osReleaseValue(release, "IMAGE_ID");
  const std::optional<std::string> image_version = osReleaseValue(release, "IMAGE_VERSION");
  nlohmann::json image = nullptr;
  if (image_id || image_version) {
    image = {{"id", image_id ? nlohmann::json(*image_id) : nlohmann::json(nullptr)},
             {"version", image_version ? nlohmann::json(*image_version) : nlohmann::json(nullptr)}};
  }
  std::error_code ec;
  const std::filesystem::space_info space = std::filesystem::space(data_dir_, ec);
  nlohmann::json data = nullptr;
  if (!ec) data = {{"total_bytes", space.capacity}, {"free_bytes", space.available}};
  return {{"version", version_},
          {"hostname", hostname},
          {"slot", slot ? nlohmann::json(*slot) : nlohmann::json(nullptr)},
          {"image", image},
          {"data", data}};
}

}  // namespace cylscan::firmware
