// SPDX-License-Identifier: Apache-2.0
#include "formats/atomic_file.hpp"

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const fs::path& target, const std::string& step, int err) {
  throw std::system_error(err, std::generic_category(),
                          "cannot write " + target.string() + " (" + step + ")");
}

// The process umask, read without changing it (umask(2) would race with other threads).
mode_t currentUmask() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Umask:", 0) == 0)
      return static_cast<mode_t>(std::strtoul(line.c_str() + 6, nullptr, 8));
  }
  return 022;
}

// Permissions of the new file: those of the file it replaces, else 0666 less the umask.
mode_t newFileMode(const fs::path& target) {
  struct stat st {};
  if (::stat(target.c_str(), &st) == 0 && S_ISREG(st.st_mode)) return st.st_mode & 07777;
  return 0666 & ~currentUmask();
}

// The temporary file: closed and removed on destruction unless it was renamed.
class TemporaryFile {
 public:
  TemporaryFile(const fs::path& target, const fs::path& dir) : target_(target) {
    std::string stem = "." + target.filename().string();
    if (stem.size() > 200) stem.resize(200);  // keep within NAME_MAX with the suffix
    const std::string pattern = (dir / (stem + ".tmp.XXXXXX")).string();
    std::vector<char> name(pattern.begin(), pattern.end());
    name.push_back('\0');
    fd_ = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd_ < 0) fail(target_, "cannot create a temporary file in " + dir.string(), errno);
    path_ = name.data();
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  ~TemporaryFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!path_.empty()) ::unlink(path_.c_str());
  }

  void write(std::span<const std::byte> data) {
    std::size_t done = 0;
    while (done < data.size()) {
      const ssize_t n = ::write(fd_, data.data() + done, data.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        fail(target_, "write " + path_.string(), errno);
      }
      done += static_cast<std::size_t>(n);
    }
  }

  void setMode(mode_t mode) {
    if (::fchmod(fd_, mode) != 0) fail(target_, "chmod " + path_.string(), errno);
  }

  void syncAndClose() {
    if (::fsync(fd_) != 0) fail(target_, "fsync " + path_.string(), errno);
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail(target_, "close " + path_.string(), errno);
  }

  void renameOverTarget() {
    if (::rename(path_.c_str(), target_.c_str()) != 0) {
      fail(target_, "rename " + path_.string() + " over it", errno);
    }
    path_.clear();  // nothing left to remove
  }

 private:
  fs::path target_;
  fs::path path_;
  int fd_ = -1;
};

}  // namespace

void writeFileAtomically(const fs::path& target, std::span<const std::byte> data) {
  if (!target.has_filename()) fail(target, "the path names no file", EISDIR);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  {
    TemporaryFile temp(target, dir);
    temp.write(data);
    temp.setMode(newFileMode(target));
    temp.syncAndClose();
    temp.renameOverTarget();
  }
  try {
    syncDirectory(dir);
  } catch (const std::system_error& e) {
    fail(target, e.what(), e.code().value());
  }
}

void syncDirectory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) {
    throw std::system_error(errno, std::generic_category(),
                            "cannot open directory " + dir.string());
  }
  const bool failed = ::fsync(fd) != 0 && errno != EINVAL;
  const int err = errno;
  ::close(fd);
  if (failed) throw std::system_error(err, std::generic_category(), "cannot fsync " + dir.string());
}

void writeFileAtomically(const fs::path& target, std::string_view text) {
  writeFileAtomically(target, std::as_bytes(std::span<const char>(text.data(), text.size())));
}

}  // namespace cylscan::formats
