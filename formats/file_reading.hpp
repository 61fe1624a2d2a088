// SPDX-License-Identifier: Apache-2.0
// Reading input files whole, with a size limit, for the format readers. Every
// fault (missing, a directory, too large, unreadable) throws InputError naming
// the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace cylscan::formats {

// The whole file; InputError if it is larger than max_bytes.
std::string readFileContents(const std::filesystem::path& file, std::uintmax_t max_bytes);

// The file parsed as JSON; InputError "not valid JSON (truncated or corrupt): …"
// on a syntax error or a number that overflows a double (1e400).
nlohmann::json readJsonFile(const std::filesystem::path& file, std::uintmax_t max_bytes);

// At most the first max_bytes of the file (fewer if the file is shorter).
std::string readFilePrefix(const std::filesystem::path& file, std::size_t max_bytes);

}  // namespace cylscan::formats
