// SPDX-License-Identifier: Apache-2.0
#include "drivers/posix_io.hpp"

#include <cerrno>
#include <system_error>
#include <utility>

#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace cylscan::drivers {

UniqueFd& UniqueFd::operator=(UniqueFd&& other) noexcept {
  if (this != &other) reset(other.release());
  return *this;
}

int UniqueFd::release() {
  return std::exchange(fd_, -1);
}

void UniqueFd::reset(int fd) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
}

MemoryMap::MemoryMap(int fd, std::size_t length, off_t offset, bool writable,
                     const std::string& what) {
  const long page = ::sysconf(_SC_PAGESIZE);
  const off_t aligned = page > 0 ? offset - offset % page : offset;
  const auto lead = static_cast<std::size_t>(offset - aligned);
  const int prot = PROT_READ | (writable ? PROT_WRITE : 0);
  void* p = ::mmap(nullptr, length + lead, prot, MAP_SHARED, fd, aligned);
  if (p == MAP_FAILED) {
    throw std::system_error(errno, std::generic_category(), "mmap of " + what);
  }
  base_ = p;
  mapped_ = length + lead;
  data_ = static_cast<const std::uint8_t*>(p) + lead;
  length_ = length;
}

MemoryMap::MemoryMap(MemoryMap&& other) noexcept
    : base_(std::exchange(other.base_, nullptr)),
      mapped_(std::exchange(other.mapped_, 0)),
      data_(std::exchange(other.data_, nullptr)),
      length_(std::exchange(other.length_, 0)) {}

MemoryMap& MemoryMap::operator=(MemoryMap&& other) noexcept {
  if (this != &other) {
    reset();
    base_ = std::exchange(other.base_, nullptr);
    mapped_ = std::exchange(other.mapped_, 0);
    data_ = std::exchange(other.data_, nullptr);
    length_ = std::exchange(other.length_, 0);
  }
  return *this;
}

void MemoryMap::reset() {
  if (base_ != nullptr) ::munmap(base_, mapped_);
  base_ = nullptr;
  mapped_ = 0;
  data_ = nullptr;
  length_ = 0;
}

int ioctlRetry(int fd, unsigned long request, void* arg) {
  int r = 0;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

}  // namespace cylscan::drivers
