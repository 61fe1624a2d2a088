// SPDX-License-Identifier: Apache-2.0
#include "firmware/http/files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <system_error>
#include <utility>

namespace cylscan::firmware::http {

OpenFile::~OpenFile() {
  if (fd_ >= 0) ::close(fd_);
}

OpenFile::OpenFile(OpenFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), size_(other.size_) {}

OpenFile& OpenFile::operator=(OpenFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    size_ = other.size_;
  }
  return *this;
}

int OpenFile::release() {
  return std::exchange(fd_, -1);
}

std::optional<OpenFile> openRegularFile(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
  if (fd < 0) return std::nullopt;
  OpenFile file(fd, 0);
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  // Back to blocking reads (O_NONBLOCK only kept a FIFO from hanging open()).
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  return OpenFile(file.release(), static_cast<std::uint64_t>(st.st_size));
}

std::optional<OpenFile> openStaticFile(const std::filesystem::path& root,
                                       std::string_view relative) {
  if (root.empty() || relative.empty()) return std::nullopt;
  std::error_code ec;
  const auto base = std::filesystem::canonical(root, ec);
  if (ec) return std::nullopt;
  const auto target = std::filesystem::canonical(base / std::filesystem::path(relative), ec);
  if (ec) return std::nullopt;
  // Confined: `target` must be `base` followed by at least one more part.
  auto b = base.begin();
  auto t = target.begin();
  for (; b != base.end(); ++b, ++t) {
    if (t == target.end() || *b != *t) return std::nullopt;
  }
  if (t == target.end()) return std::nullopt;
  return openRegularFile(target);
}

}  // namespace cylscan::firmware::http
