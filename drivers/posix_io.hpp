// SPDX-License-Identifier: Apache-2.0
// Owners of POSIX resources for the device backends: a file descriptor and a
// memory mapping, each released exactly once.
#pragma once

#include <sys/types.h>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace cylscan::drivers {

class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { reset(); }
  UniqueFd(UniqueFd&& other) noexcept : fd_(other.release()) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept;
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;

  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  int release();
  void reset(int fd = -1);

 private:
  int fd_ = -1;
};

// A shared read-only or read-write mapping of `length` bytes of `fd` from
// `offset` (any offset: the page alignment is handled inside).
class MemoryMap {
 public:
  MemoryMap() = default;
  // Throws std::system_error naming `what` when mmap fails.
  MemoryMap(int fd, std::size_t length, off_t offset, bool writable, const std::string& what);
  ~MemoryMap() { reset(); }
  MemoryMap(MemoryMap&& other) noexcept;
  MemoryMap& operator=(MemoryMap&& other) noexcept;
  MemoryMap(const MemoryMap&) = delete;
  MemoryMap& operator=(const MemoryMap&) = delete;

  std::span<const std::uint8_t> bytes() const { return {data_, length_}; }
  void reset();

 private:
  void* base_ = nullptr;    // what mmap returned
  std::size_t mapped_ = 0;  // what mmap mapped
  const std::uint8_t* data_ = nullptr;
  std::size_t length_ = 0;
};

// ioctl() retried on EINTR; returns its result (errno set on -1).
int ioctlRetry(int fd, unsigned long request, void* arg);

}  // namespace cylscan::drivers
