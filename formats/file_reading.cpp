// SPDX-License-Identifier: Apache-2.0
#include "formats/file_reading.hpp"

#include <cerrno>
#include <system_error>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "formats/input_error.hpp"

namespace cylscan::formats {
namespace {

std::string errnoText(int err) {
  return std::generic_category().message(err);
}

// An open read-only descriptor of a regular file, closed on destruction.
class InputFile {
 public:
  explicit InputFile(const std::filesystem::path& file) : file_(file) {
    fd_ = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) throw InputError(file, "cannot open: " + errnoText(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0) {
      const int err = errno;
      ::close(fd_);
      throw InputError(file, "cannot stat: " + errnoText(err));
    }
    if (S_ISDIR(st.st_mode)) {
      ::close(fd_);
      throw InputError(file, "is a directory, expected a file");
    }
    if (!S_ISREG(st.st_mode)) {
      ::close(fd_);
      throw InputError(file, "is not a regular file");
    }
    size_ = static_cast<std::uintmax_t>(st.st_size);
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  ~InputFile() { ::close(fd_); }

  std::uintmax_t size() const { return size_; }

  // Reads up to max_bytes; stops early at the end of the file.
  std::string read(std::size_t max_bytes) const {
    std::string data;
    data.resize(max_bytes);
    std::size_t done = 0;
    while (done < max_bytes) {
      const ssize_t n = ::read(fd_, data.data() + done, max_bytes - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        throw InputError(file_, "cannot read: " + errnoText(errno));
      }
      if (n == 0) break;
      done += static_cast<std::size_t>(n);
    }
    data.resize(done);
    return data;
  }

 private:
  std::filesystem::path file_;
  int fd_ = -1;
  std::uintmax_t size_ = 0;
};

}  // namespace

std::string readFileContents(const std::filesystem::path& file, std::uintmax_t max_bytes) {
  const InputFile input(file);
  if (input.size() > max_bytes) {
    throw InputError(file, "is " + std::to_string(input.size()) +
                               " bytes, more than the limit of " + std::to_string(max_bytes) +
                               " bytes for this kind of file");
  }
  // One byte more than the size detects a file that grew while being read.
  std::string data = input.read(static_cast<std::size_t>(input.size()) + 1);
  if (data.size() != input.size()) throw InputError(file, "changed size while being read");
  return data;
}

nlohmann::json readJsonFile(const std::filesystem::path& file, std::uintmax_t max_bytes) {
  const std::string text = readFileContents(file, max_bytes);
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error; out_of_range for 1e400
    std::string what = e.what();
    const auto end = what.find("] ");
    if (what.rfind("[json.exception", 0) == 0 && end != std::string::npos) what.erase(0, end + 2);
    throw InputError(file, "not valid JSON (truncated or corrupt): " + what);
  }
}

std::string readFilePrefix(const std::filesystem::path& file, std::size_t max_bytes) {
  const InputFile input(file);
  return input.read(max_bytes);
}

}  // namespace cylscan::formats
