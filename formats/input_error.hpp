// SPDX-License-Identifier: Apache-2.0
// Bad input from outside (a file, a request): the message names the file and the fault.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace cylscan::formats {

class InputError : public std::runtime_error {
 public:
  InputError(const std::filesystem::path& file, const std::string& fault)
      : std::runtime_error(file.string() + ": " + fault), file_(file) {}
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
};

}  // namespace cylscan::formats
