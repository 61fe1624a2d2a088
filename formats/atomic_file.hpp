// SPDX-License-Identifier: Apache-2.0
// Writes that never leave a half-written file behind: write to a temporary
// name in the same directory, fsync, rename over the target, fsync the directory.
#pragma once

#include <cstddef>
#include <filesystem>
#include <span>
#include <string_view>

namespace cylscan::formats {

// Throws std::system_error naming the path on any failure; the target is then
// untouched and the temporary removed.
void writeFileAtomically(const std::filesystem::path& target, std::span<const std::byte> data);
void writeFileAtomically(const std::filesystem::path& target, std::string_view text);

// fsync of a directory, which makes a rename or a removal inside it durable.
// Throws std::system_error naming the directory. A file system that cannot
// sync a directory (EINVAL) is not an error: the rename is as durable as it gets.
void syncDirectory(const std::filesystem::path& dir);

}  // namespace cylscan::formats
