// SPDX-License-Identifier: Apache-2.0
#include "drivers/toml_reader.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace cylscan::drivers {

namespace {

std::string describe(const std::string& file, int line, const std::string& key,
                     const std::string& fault) {
  std::ostringstream out;
  out << file;
  if (line > 0) out << ":" << line;
  out << ": ";
  if (!key.empty()) out << key << ": ";
  out << fault;
  return out.str();
}

}  // namespace

ConfigError::ConfigError(const std::string& file, int line, const std::string& key,
                         const std::string& fault)
    : std::invalid_argument(describe(file, line, key, fault)),
      file_(file),
      line_(line),
      key_(key) {}

toml::table parseToml(std::string_view text, const std::string& file) {
  try {
    return toml::parse(text, file);
  } catch (const toml::parse_error& e) {
    throw ConfigError(file, static_cast<int>(e.source().begin.line), "",
                      std::string(e.description()));
  }
}

std::string readConfigText(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file, 0, "", "cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ConfigError(file, 0, "", "cannot read the file");
  return std::move(text).str();
}

toml::table parseTomlFile(const std::string& file) {
  return parseToml(readConfigText(file), file);
}

TableReader::TableReader(const toml::table& table, std::string file, std::string path)
    : table_(table), file_(std::move(file)), path_(std::move(path)) {}

std::string TableReader::keyPath(std::string_view key) const {
  if (path_.empty()) return std::string(key);
  return path_ + "." + std::string(key);
}

int TableReader::lineOf(std::string_view key) const {
  if (const toml::node* n = table_.get(key)) return static_cast<int>(n->source().begin.line);
  return static_cast<int>(table_.source().begin.line);
}

void TableReader::fail(std::string_view key, const std::string& fault) const {
  throw ConfigError(file_, lineOf(key), keyPath(key), fault);
}

void TableReader::require(bool condition, std::string_view key, const std::string& fault) const {
  if (!condition) fail(key, fault);
}

bool TableReader::has(std::string_view key) const {
  return table_.get(key) != nullptr;
}

const toml::node* TableReader::node(std::string_view key) {
  const toml::node* n = table_.get(key);
  if (n != nullptr) used_.emplace(key);
  return n;
}

double TableReader::number(std::string_view key, double fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  double value = 0;
  if (auto i = n->value_exact<std::int64_t>()) {
    value = static_cast<double>(*i);
  } else if (auto d = n->value_exact<double>()) {
    value = *d;
  } else {
    fail(key, "must be a number");
  }
  require(std::isfinite(value), key, "must be finite");
  return value;
}

double TableReader::requiredNumber(std::string_view key) {
  require(has(key), key, "is required");
  return number(key, 0);
}

int TableReader::integer(std::string_view key, int fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  auto i = n->value_exact<std::int64_t>();
  if (!i) fail(key, "must be an integer");
  require(*i >= -2147483647 && *i <= 2147483647, key, "is out of range");
  return static_cast<int>(*i);
}

std::int64_t TableReader::integerIn(std::string_view key, std::int64_t fallback, std::int64_t lo,
                                    std::int64_t hi) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  auto i = n->value_exact<std::int64_t>();
  if (!i) fail(key, "must be an integer");
  require(*i >= lo && *i <= hi, key,
          std::to_string(*i) + " is not in " + std::to_string(lo) + ".." + std::to_string(hi));
  return *i;
}

bool TableReader::boolean(std::string_view key, bool fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  auto b = n->value_exact<bool>();
  if (!b) fail(key, "must be true or false");
  return *b;
}

std::string TableReader::string(std::string_view key, const std::string& fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  auto s = n->value_exact<std::string>();
  if (!s) fail(key, "must be a string");
  return *s;
}

std::filesystem::path TableReader::path(std::string_view key,
                                        const std::filesystem::path& fallback) {
  if (!has(key)) return fallback;
  const std::filesystem::path p = string(key, "");
  require(!p.empty(), key, "must not be empty");
  return p.is_absolute() ? p : std::filesystem::path(file_).parent_path() / p;
}

namespace {

template <std::size_t N>
std::array<double, N> numbers(TableReader& reader, const toml::node* n, std::string_view key) {
  const toml::array* a = n->as_array();
  if (a == nullptr || a->size() != N) {
    reader.fail(key, "must be an array of " + std::to_string(N) + " numbers");
  }
  std::array<double, N> out{};
  for (std::size_t i = 0; i < N; ++i) {
    const toml::node& e = *a->get(i);
    if (auto v = e.value_exact<std::int64_t>()) {
      out[i] = static_cast<double>(*v);
    } else if (auto d = e.value_exact<double>()) {
      out[i] = *d;
    } else {
      reader.fail(key, "must be an array of " + std::to_string(N) + " numbers");
    }
    reader.require(std::isfinite(out[i]), key, "must be finite");
  }
  return out;
}

}  // namespace

std::array<double, 3> TableReader::vec3(std::string_view key,
                                        const std::array<double, 3>& fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  return numbers<3>(*this, n, key);
}

std::array<double, 2> TableReader::vec2(std::string_view key,
                                        const std::array<double, 2>& fallback) {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  return numbers<2>(*this, n, key);
}

const toml::table* TableReader::table(std::string_view key) {
  const toml::node* n = node(key);
  if (n == nullptr) return nullptr;
  if (!n->is_table()) fail(key, "must be a table");
  return n->as_table();
}

const toml::array* TableReader::array(std::string_view key) {
  const toml::node* n = node(key);
  if (n == nullptr) return nullptr;
  if (!n->is_array()) fail(key, "must be an array");
  return n->as_array();
}

double TableReader::positive(std::string_view key, double fallback) {
  const double v = number(key, fallback);
  require(v > 0, key, "must be > 0");
  return v;
}

double TableReader::nonNegative(std::string_view key, double fallback) {
  const double v = number(key, fallback);
  require(v >= 0, key, "must be >= 0");
  return v;
}

void TableReader::finish() const {
  for (const auto& [k, v] : table_) {
    if (!used_.contains(k.str())) {
      throw ConfigError(file_, static_cast<int>(k.source().begin.line), keyPath(k.str()),
                        "unknown key");
    }
  }
}

}  // namespace cylscan::drivers
