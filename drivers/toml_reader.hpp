// SPDX-License-Identifier: Apache-2.0
// Strict reading of TOML tables, for every TOML file cylscan reads (board.toml,
// the virtual head's head.toml and scenes, cylscan.toml): every key must be
// known, every value checked, and every error names the file, the line and the key.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>

#include <toml++/toml.h>

namespace cylscan::drivers {

// Bad content in a configuration file: "FILE:LINE: KEY: FAULT" (line 0: not
// known, e.g. a command-line flag, whose name is then the file). A
// std::invalid_argument, so the command line reports it as bad input (exit 2).
class ConfigError : public std::invalid_argument {
 public:
  ConfigError(const std::string& file, int line, const std::string& key, const std::string& fault);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& key() const { return key_; }

 private:
  std::string file_;
  int line_;
  std::string key_;
};

// Parses TOML text; a syntax error becomes a ConfigError with its line. `file`
// names the text in messages.
toml::table parseToml(std::string_view text, const std::string& file);
// The whole text of a file; ConfigError (line 0) when it cannot be read.
std::string readConfigText(const std::string& file);
// readConfigText, then parseToml.
toml::table parseTomlFile(const std::string& file);

// A view of one table that tracks which keys were read. finish() rejects the rest.
class TableReader {
 public:
  // `path` is the table's dotted name in messages ("projector", "camera[1]").
  TableReader(const toml::table& table, std::string file, std::string path);

  bool has(std::string_view key) const;
  double number(std::string_view key, double fallback);
  double requiredNumber(std::string_view key);
  int integer(std::string_view key, int fallback);
  // An integer in [lo, hi]: "V is not in LO..HI" otherwise.
  std::int64_t integerIn(std::string_view key, std::int64_t fallback, std::int64_t lo,
                         std::int64_t hi);
  bool boolean(std::string_view key, bool fallback);
  std::string string(std::string_view key, const std::string& fallback);
  // A non-empty string naming a path; a relative one is relative to the file's folder.
  std::filesystem::path path(std::string_view key, const std::filesystem::path& fallback);
  std::array<double, 3> vec3(std::string_view key, const std::array<double, 3>& fallback);
  std::array<double, 2> vec2(std::string_view key, const std::array<double, 2>& fallback);
  const toml::table* table(std::string_view key);  // nullptr when absent
  const toml::array* array(std::string_view key);  // nullptr when absent

  // Value checks: throw a ConfigError naming the key unless the condition holds.
  void require(bool condition, std::string_view key, const std::string& fault) const;
  double positive(std::string_view key, double fallback);
  double nonNegative(std::string_view key, double fallback);

  // Throws for the first key that was not read.
  void finish() const;

  [[noreturn]] void fail(std::string_view key, const std::string& fault) const;
  const std::string& file() const { return file_; }
  std::string keyPath(std::string_view key) const;

 private:
  const toml::node* node(std::string_view key);
  int lineOf(std::string_view key) const;

  const toml::table& table_;
  std::string file_;
  std::string path_;
  std::set<std::string, std::less<>> used_;
};

}  // namespace cylscan::drivers
