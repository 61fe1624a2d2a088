// SPDX-License-Identifier: Apache-2.0
// Files the HTTP API sends: opened once, checked to be regular files, handed
// to libmicrohttpd as a descriptor (it streams them with sendfile).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string_view>

namespace cylscan::firmware::http {

// An open, read-only regular file; closes it unless released.
class OpenFile {
 public:
  OpenFile(int fd, std::uint64_t size) : fd_(fd), size_(size) {}
  ~OpenFile();
  OpenFile(OpenFile&& other) noexcept;
  OpenFile& operator=(OpenFile&& other) noexcept;
  OpenFile(const OpenFile&) = delete;
  OpenFile& operator=(const OpenFile&) = delete;

  int fd() const { return fd_; }
  std::uint64_t size() const { return size_; }
  int release();  // the descriptor, now the caller's to close

 private:
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

// `path` opened for reading when it is a regular file (after symlinks);
// nullopt when it does not exist or is anything else.
std::optional<OpenFile> openRegularFile(const std::filesystem::path& path);

// The page's file `relative` (a path the router accepted: no '.'/'..'
// segments, no backslash, no '%') under `root`, confined there: after
// resolving symlinks it must still be inside `root`, and a regular file.
std::optional<OpenFile> openStaticFile(const std::filesystem::path& root,
                                       std::string_view relative);

}  // namespace cylscan::firmware::http
